//! Sweeps over the study: sensitivity to the mismatch's size (all five
//! parameters scaled together) and an ablation of the calibration pipeline
//! (its first stage only, the full pipeline, the oracle) for each preset.

use std::path::Path;

use cassi_core::calib::Preset;
use cassi_core::recon::Model;
use cassi_core::{Mask, Mismatch};

use crate::protocol::{SceneProgress, Study, prepare, reconstruct_and_score};
use crate::study::{Event, RunOptions, SceneSource, run_study};
use crate::summary::summarize;
use crate::sweep_rows::{AblationRow, AblationVariant, SensitivityPoint};

/// The paper's mismatch scaled by `s`: dx, dy, θ, α × s, a1 = stride + s·(2.04 − 2).
pub fn scaled_mismatch(s: f64, stride: f64) -> Mismatch {
    let p = Mismatch::paper();
    Mismatch {
        dx: p.dx * s,
        dy: p.dy * s,
        theta_deg: p.theta_deg * s,
        a1: stride + s * (p.a1 - 2.0),
        alpha_deg: p.alpha_deg * s,
        ..Mismatch::nominal(2.0)
    }
}

/// The study at each scale of the paper's mismatch, each in its own folder
/// `<out>/sensitivity/<preset>_scale<s>` (resumable like any study).
pub fn sensitivity(
    base: &Study,
    scales: &[f64],
    scenes: &[SceneSource],
    mask: &Mask,
    out: &Path,
    resume: bool,
    on_event: &mut dyn FnMut(f64, Event<'_>),
) -> anyhow::Result<Vec<SensitivityPoint>> {
    scales
        .iter()
        .map(|&scale| {
            let study = Study {
                mismatch: scaled_mismatch(scale, base.stride),
                ..base.clone()
            };
            let dir = out
                .join("sensitivity")
                .join(format!("{}_scale{scale}", base.preset.name()));
            let results = run_study(
                &study,
                scenes,
                mask,
                &dir,
                RunOptions {
                    resume,
                    ..RunOptions::default()
                },
                &mut |e| {
                    on_event(scale, e);
                    Ok(())
                },
            )?;
            Ok(SensitivityPoint {
                scale,
                mismatch: study.mismatch,
                summary: summarize(&results),
            })
        })
        .collect()
}

/// For each preset: calibrate every scene once, then reconstruct with the
/// nominal, search-only, full and true parameters (same measurement, same
/// solver). Scenes are loaded one at a time; `on_step` hears a
/// [`SceneProgress::Step`] per scene and each calibration stage.
pub fn ablation(
    base: &Study,
    presets: &[Preset],
    scenes: &[SceneSource],
    mask: &Mask,
    on_step: &mut dyn FnMut(SceneProgress<'_>),
) -> anyhow::Result<Vec<AblationRow>> {
    let mut rows = Vec::new();
    for preset in presets {
        let study = Study {
            preset: preset.clone(),
            ..base.clone()
        };
        let name = preset.name();
        // sums over scenes per (method, variant): psnr, squared pose error
        let mut sums =
            vec![vec![(0.0f64, 0.0f64); AblationVariant::ALL.len()]; study.methods.len()];
        let mut calib_secs = 0.0;
        for (i, source) in scenes.iter().enumerate() {
            on_step(SceneProgress::Step(&format!("{name}: {}", source.name())));
            let scene = source.load()?;
            // only its calibration stages: the scene is the counted step
            let prepared = prepare(&scene, mask, &study, i as u64, &mut |p| {
                if let SceneProgress::CalibrationStage(_) = p {
                    on_step(p)
                }
            })?;
            calib_secs += prepared.calibration.seconds;
            let search = search_only(&prepared.calibration.stages, preset)
                .unwrap_or(prepared.calibration.reconstruction_parameters());
            for (mi, method) in study.methods.iter().enumerate() {
                for (vi, variant) in AblationVariant::ALL.iter().enumerate() {
                    let params = match variant {
                        AblationVariant::Nominal => Mismatch::nominal(study.stride),
                        AblationVariant::SearchOnly => search,
                        AblationVariant::Full => prepared.calibration.reconstruction_parameters(),
                        AblationVariant::Oracle => study.mismatch,
                    };
                    let assumed =
                        Model::new(mask, scene.bands(), study.stride, params, study.instrument)?;
                    let (metrics, _, _) =
                        reconstruct_and_score(&scene, &prepared.measurement, &assumed, method)?;
                    let t = study.mismatch;
                    let e2 = (params.dx - t.dx).powi(2)
                        + (params.dy - t.dy).powi(2)
                        + (params.theta_deg - t.theta_deg).powi(2);
                    sums[mi][vi].0 += metrics.psnr;
                    sums[mi][vi].1 += e2 / 3.0;
                }
            }
        }
        let n = scenes.len().max(1) as f64;
        for (mi, method) in study.methods.iter().enumerate() {
            for (vi, variant) in AblationVariant::ALL.iter().enumerate() {
                rows.push(AblationRow {
                    preset: name.to_string(),
                    method: method.name().to_string(),
                    variant: *variant,
                    label: variant.label(preset).to_string(),
                    psnr: sums[mi][vi].0 / n,
                    pose_rmse_px: (sums[mi][vi].1 / n).sqrt(),
                    calibration_seconds_mean: calib_secs / n,
                });
            }
        }
    }
    Ok(rows)
}

/// The parameters after a preset's search stages (before any refinement).
fn search_only(stages: &[cassi_core::calib::StageReport], preset: &Preset) -> Option<Mismatch> {
    Some(
        stages
            .get(preset.search_stages().checked_sub(1)?)?
            .parameters,
    )
}
