//! Aggregates over scenes: mean metrics per method and scenario, gains, the
//! recovery ratio ρ = (III − II)/(IV − II), parameter RMSE and timings.

use serde::{Deserialize, Serialize};

use cassi_core::Parameter;
use cassi_core::stats::median;

use crate::protocol::{ParameterErrors, Scenario, SceneResult};

/// Means over scenes of one method in one scenario.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanMetrics {
    pub scenario: Scenario,
    pub psnr: f64,
    pub psnr_band_mean: f64,
    pub ssim: f64,
    pub sam_deg: f64,
    pub seconds: f64,
}

/// One method across the study.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MethodSummary {
    pub method: String,
    pub scenarios: Vec<MeanMetrics>,
    /// Mean PSNR gain of calibration, III − II, dB.
    pub calibration_gain_db: f64,
    /// Mean PSNR the mismatch costs, IV − II, dB.
    pub mismatch_loss_db: f64,
    /// ρ = mean(III − II) / mean(IV − II): the share of the oracle gap that
    /// calibration recovers (1 = all of it).
    pub recovery_ratio: f64,
    /// ρ per scene, same order as the scenes.
    pub recovery_ratio_per_scene: Vec<f64>,
}

impl MethodSummary {
    pub fn scenario(&self, s: Scenario) -> Option<&MeanMetrics> {
        self.scenarios.iter().find(|m| m.scenario == s)
    }
}

/// The whole study at a glance.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Summary {
    pub scenes: Vec<String>,
    pub methods: Vec<MethodSummary>,
    /// Root-mean-square calibration error per parameter.
    pub parameter_rmse: ParameterErrors,
    pub calibration_seconds_median: f64,
    pub calibration_seconds_mean: f64,
    /// Wall time of all scenes (calibration and every reconstruction).
    pub total_seconds: f64,
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Summarises `results` (scenes in the order given).
pub fn summarize(results: &[SceneResult]) -> Summary {
    let mut methods: Vec<String> = Vec::new();
    for r in results {
        for o in &r.outcomes {
            if !methods.contains(&o.method) {
                methods.push(o.method.clone());
            }
        }
    }
    let psnr = |r: &SceneResult, m: &str, s: Scenario| r.outcome(m, s).map(|o| o.metrics.psnr);
    let methods = methods
        .into_iter()
        .map(|method| {
            let scenarios = Scenario::ALL
                .iter()
                .filter_map(|&s| {
                    let outs: Vec<_> = results
                        .iter()
                        .filter_map(|r| r.outcome(&method, s))
                        .collect();
                    (!outs.is_empty()).then(|| MeanMetrics {
                        scenario: s,
                        psnr: mean(outs.iter().map(|o| o.metrics.psnr)),
                        psnr_band_mean: mean(outs.iter().map(|o| o.metrics.psnr_band_mean)),
                        ssim: mean(outs.iter().map(|o| o.metrics.ssim)),
                        sam_deg: mean(outs.iter().map(|o| o.metrics.sam_deg)),
                        seconds: mean(outs.iter().map(|o| o.seconds)),
                    })
                })
                .collect();
            let gains: Vec<(f64, f64)> = results
                .iter()
                .filter_map(|r| {
                    let ii = psnr(r, &method, Scenario::Assumed)?;
                    Some((
                        psnr(r, &method, Scenario::Corrected)? - ii,
                        psnr(r, &method, Scenario::Oracle)? - ii,
                    ))
                })
                .collect();
            let calibration_gain_db = mean(gains.iter().map(|g| g.0));
            let mismatch_loss_db = mean(gains.iter().map(|g| g.1));
            MethodSummary {
                method,
                scenarios,
                calibration_gain_db,
                mismatch_loss_db,
                recovery_ratio: calibration_gain_db / mismatch_loss_db,
                recovery_ratio_per_scene: gains.iter().map(|g| g.0 / g.1).collect(),
            }
        })
        .collect();
    let n = results.len().max(1) as f64;
    let rmse = |p: Parameter| {
        let sq: f64 = results.iter().map(|r| r.errors.get(p).powi(2)).sum();
        (sq / n).sqrt()
    };
    let calib_secs: Vec<f64> = results.iter().map(|r| r.calibration.seconds).collect();
    Summary {
        scenes: results.iter().map(|r| r.scene.clone()).collect(),
        methods,
        parameter_rmse: ParameterErrors::from_fn(rmse),
        calibration_seconds_median: median(&calib_secs),
        calibration_seconds_mean: mean(calib_secs.into_iter()),
        total_seconds: results.iter().map(|r| r.seconds).sum(),
    }
}
