//! The `default` preset: a correlation estimate of the mask pose
//! (milliseconds), a Nelder–Mead refinement of (dx, dy, θ) on the proxy
//! score from several starts, an a1 search (over the exact rounding-pattern
//! intervals for the `rounded` model), then a final joint refinement.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::nelder_mead::nelder_mead;
use super::uncertainty::curvature_uncertainty;
use super::{Calibration, CalibrationProblem, ProxyParams, StageReport, init, psi};
use crate::error::Result;
use crate::optics::DispersionModel;
use crate::params::Mismatch;

/// Settings of the `default` preset.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DefaultPreset {
    pub stride: f64,
    /// Largest |dx|, |dy| searched by the correlation stage, pixels.
    pub shift_range: usize,
    pub proxy: ProxyParams,
    /// a1 searched over [stride − span, stride + span].
    pub a1_span: f64,
    pub max_evaluations: usize,
    /// Proxy iterations of the search stages (2–3); `proxy` is used for the
    /// final refinement and the reported score.
    pub search_iterations: usize,
}

impl Default for DefaultPreset {
    fn default() -> Self {
        Self {
            stride: 2.0,
            shift_range: 5,
            proxy: ProxyParams::default(),
            a1_span: 0.12,
            max_evaluations: 400,
            search_iterations: 5,
        }
    }
}

/// The breakpoints where some band's rounded offset changes: a1 values with
/// a1·k·cos α = j + ½. Between two consecutive ones the rounded model is the
/// same operator.
fn rounding_intervals(bands: usize, alpha_deg: f64, lo: f64, hi: f64) -> Vec<(f64, f64)> {
    let c = alpha_deg.to_radians().cos();
    let mut cuts = vec![lo, hi];
    for k in 1..bands {
        let kc = k as f64 * c;
        let (jlo, jhi) = (
            (lo * kc - 0.5).floor() as i64,
            (hi * kc - 0.5).ceil() as i64,
        );
        for j in jlo..=jhi {
            let a = (j as f64 + 0.5) / kc;
            if a > lo && a < hi {
                cuts.push(a);
            }
        }
    }
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    cuts.windows(2).map(|w| (w[0], w[1])).collect()
}

/// `from` with slope `a1`, dx moved so the mean band position is unchanged:
/// the data pin dx + a1·k̄ (k̄ = (L−1)/2) far better than dx and a1 apart,
/// so a1 must be searched along that line.
fn along_mean_dispersion(from: &Mismatch, a1: f64, bands: usize) -> Mismatch {
    let k_mean = (bands as f64 - 1.0) / 2.0;
    let c = from.alpha_deg.to_radians().cos();
    Mismatch {
        a1,
        dx: from.dx - (a1 - from.a1) * k_mean * c,
        ..*from
    }
}

/// Runs the `default` preset. `on_stage` sees each stage as it finishes.
pub fn calibrate_default(
    problem: &CalibrationProblem<'_>,
    preset: &DefaultPreset,
    on_stage: &mut dyn FnMut(&StageReport),
) -> Result<Calibration> {
    problem.validate()?;
    let t_all = Instant::now();
    let proxy = preset.proxy;
    let mut stages = Vec::new();
    let mut push = |stages: &mut Vec<StageReport>, r: StageReport| {
        on_stage(&r);
        stages.push(r);
    };
    let score = |m: &Mismatch| problem.score(m, &proxy).unwrap_or(f64::INFINITY);
    let search_proxy = ProxyParams {
        iterations: preset.search_iterations,
        ..proxy
    };
    let search = |m: &Mismatch| problem.score(m, &search_proxy).unwrap_or(f64::INFINITY);

    // 1. global shift estimate
    let t = Instant::now();
    let (dx0, dy0, theta0) = init::correlation_pose(
        problem.measurement,
        problem.nominal_mask,
        problem.bands,
        preset.stride,
        preset.shift_range,
    )?;
    let mut best = Mismatch {
        dx: dx0,
        dy: dy0,
        theta_deg: theta0.clamp(-crate::params::MAX_ANGLE_DEG, crate::params::MAX_ANGLE_DEG),
        ..Mismatch::nominal(preset.stride)
    };
    let s0 = score(&best);
    push(
        &mut stages,
        StageReport {
            name: "correlation".into(),
            evaluations: 1,
            seconds: t.elapsed().as_secs_f64(),
            parameters: best,
            score: s0,
        },
    );

    // 2. (dx, dy, θ) from three rotation starts
    let t = Instant::now();
    let mut evals = 0;
    // θ starts: around the correlation fit and at fixed angles (the fit can
    // miss on scenes with little texture)
    let fitted = best.theta_deg;
    let thetas = [fitted - 0.25, fitted, fitted + 0.25, -0.5, 0.0, 0.5];
    // (dx, dy) starts: the pose fit's and the global correlation peak's
    let (gdx, gdy) = init::correlation_shift(
        problem.measurement,
        problem.nominal_mask,
        problem.bands,
        preset.stride,
        preset.shift_range,
    )?;
    let mut starts: Vec<(f64, Mismatch)> = Vec::new();
    for (sdx, sdy) in [(best.dx, best.dy), (gdx, gdy)] {
        for &th in &thetas {
            let m = Mismatch {
                dx: sdx,
                dy: sdy,
                theta_deg: th,
                ..best
            };
            evals += 1;
            starts.push((search(&m), m));
        }
    }
    starts.sort_by(|a, b| a.0.total_cmp(&b.0));
    // refine the two most promising starts: the best-looking start can sit
    // in the wrong basin
    let mut s = f64::INFINITY;
    for (_, start) in starts.iter().take(2) {
        let (v, sv, n) = nelder_mead(
            |v| search(&psi(v, start)),
            &[start.dx, start.dy, start.theta_deg],
            &[0.25, 0.25, 0.25],
            preset.max_evaluations / 4,
            &[0.005, 0.005, 0.005],
            1e-6,
        );
        evals += n;
        if sv < s {
            s = sv;
            best = psi(&v, start);
        }
    }
    push(
        &mut stages,
        StageReport {
            name: "refine dx, dy, θ".into(),
            evaluations: evals,
            seconds: t.elapsed().as_secs_f64(),
            parameters: best,
            score: s,
        },
    );

    // 3. dispersion
    let t = Instant::now();
    let (lo, hi) = (
        preset.stride - preset.a1_span,
        preset.stride + preset.a1_span,
    );
    let mut evals = 0;
    match problem.model {
        DispersionModel::Rounded => {
            // With a1 off, stage 2 aligned dx with *some* group of bands;
            // a candidate a1 moves band k by δ_k, so the matching dx is
            // dx − δ for one of the distinct δ_k: try each.
            let mut best_s = f64::INFINITY;
            let from = best;
            let c = from.alpha_deg.to_radians().cos();
            let offset = |a1: f64, k: usize| (a1 * k as f64 * c).round_ties_even();
            let intervals = rounding_intervals(problem.bands, best.alpha_deg, lo, hi);
            // coarse: the intervals holding an a1 grid of step 0.01; fine: every
            // interval within ±0.012 of the best coarse one
            let mut tried = vec![false; intervals.len()];
            let mut try_interval =
                |i: usize, best: &mut Mismatch, best_s: &mut f64, evals: &mut usize| {
                    if tried[i] {
                        return;
                    }
                    tried[i] = true;
                    let (a, b) = intervals[i];
                    let a1 = 0.5 * (a + b);
                    let mut deltas: Vec<f64> = (0..problem.bands)
                        .map(|k| offset(a1, k) - offset(from.a1, k))
                        .collect();
                    deltas.sort_by(f64::total_cmp);
                    deltas.dedup();
                    for delta in deltas {
                        let m = Mismatch {
                            a1,
                            dx: from.dx - delta,
                            ..from
                        };
                        let s = search(&m);
                        *evals += 1;
                        if s < *best_s {
                            *best_s = s;
                            *best = m;
                        }
                    }
                };
            let steps = ((hi - lo) / 0.01).round() as usize;
            for j in 0..=steps {
                let g = lo + (hi - lo) * j as f64 / steps as f64;
                if let Some(i) = intervals.iter().position(|&(a, b)| a <= g && g <= b) {
                    try_interval(i, &mut best, &mut best_s, &mut evals);
                }
            }
            let centre = best.a1;
            let near: Vec<usize> = (0..intervals.len())
                .filter(|&i| intervals[i].1 >= centre - 0.012 && intervals[i].0 <= centre + 0.012)
                .collect();
            for i in near {
                try_interval(i, &mut best, &mut best_s, &mut evals);
            }
        }
        DispersionModel::Subpixel => {
            let mut best_s = f64::INFINITY;
            let from = best;
            let mut a1 = lo;
            while a1 <= hi + 1e-12 {
                let m = along_mean_dispersion(&from, a1, problem.bands);
                let s = search(&m);
                evals += 1;
                if s < best_s {
                    best_s = s;
                    best = m;
                }
                a1 += 0.01;
            }
        }
    }
    push(
        &mut stages,
        StageReport {
            name: "dispersion a1".into(),
            evaluations: evals,
            seconds: t.elapsed().as_secs_f64(),
            parameters: best,
            score: score(&best),
        },
    );

    // 4. joint refinement (a1 and α in the simplex for the subpixel model)
    let t = Instant::now();
    let base = best;
    let (x0, steps, tol): (Vec<f64>, Vec<f64>, Vec<f64>) = match problem.model {
        DispersionModel::Rounded => (
            vec![base.dx, base.dy, base.theta_deg],
            vec![0.05, 0.05, 0.05],
            vec![0.002, 0.002, 0.002],
        ),
        DispersionModel::Subpixel => (
            vec![base.dx, base.dy, base.theta_deg, base.a1, base.alpha_deg],
            vec![0.05, 0.05, 0.05, 0.005, 0.3],
            vec![0.002, 0.002, 0.002, 0.0005, 0.02],
        ),
    };
    let (v, s, n) = nelder_mead(
        |v| score(&psi(v, &base)),
        &x0,
        &steps,
        preset.max_evaluations / 2,
        &tol,
        1e-7,
    );
    best = psi(&v, &base);
    push(
        &mut stages,
        StageReport {
            name: "joint refinement".into(),
            evaluations: n,
            seconds: t.elapsed().as_secs_f64(),
            parameters: best,
            score: s,
        },
    );

    let (uncertainty, uncertainty_evals) = curvature_uncertainty(problem, &best, s, &proxy);
    let nominal_score = score(&Mismatch::nominal(preset.stride));
    // + the uncertainty probes and the nominal score
    let evaluations = stages.iter().map(|s| s.evaluations).sum::<usize>() + uncertainty_evals + 1;
    Ok(Calibration {
        preset: "default".into(),
        model: problem.model,
        parameters: best,
        score: s,
        nominal_score,
        uncertainty,
        stages,
        seconds: t_all.elapsed().as_secs_f64(),
        evaluations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_intervals_cover_the_range_and_break_where_offsets_change() {
        let iv = rounding_intervals(28, 0.0, 1.9, 2.1);
        assert_eq!(iv.first().unwrap().0, 1.9);
        assert_eq!(iv.last().unwrap().1, 2.1);
        // a1 = 2.04 lies in the interval [26.5/13, 24.5/12] = [2.03846, 2.04167]
        let hit = iv.iter().find(|(a, b)| *a <= 2.04 && 2.04 < *b).unwrap();
        assert!(
            (hit.0 - 26.5 / 13.0).abs() < 1e-12 && (hit.1 - 24.5 / 12.0).abs() < 1e-12,
            "{hit:?}"
        );
    }
}
