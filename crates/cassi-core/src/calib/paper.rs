//! The `paper` preset: Algorithm 1 of the paper (§4.3) with one coordinate
//! convention throughout and exact gradients.
//!
//! 0. 9×9×7 grid over dx, dy ∈ [−3, 3] px, θ ∈ [−1°, 1°], 8-iteration proxy.
//! 1. 5×5×3 grids (±0.75 px, ±⅓°) around the 5 best, 12 iterations.
//! 2. Adam through the unrolled proxy ([`super::gradient`]): 2A dx; 2B dy, θ;
//!    2C all three; cosine-annealed rates, gradient norm clipped at 0.5,
//!    parameters clamped to the box, last iterate kept.
//! 3. Grid-best vs gradient-best by a 15-iteration score (at the nominal
//!    a1, so both are compared under the same dispersion).
//! 4. a1 over 1.90 … 2.10 (step 0.01) with that pose; the score is per
//!    measurement pixel over a fixed detector area, so a candidate a1 that
//!    changes the model's width gains nothing from it (the reference code's
//!    a1 defect). α is not estimated (the paper returns 0).
//!
//! The proxy's per-stage settings are those of the reference code
//! (seed-code notes §6).

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::adam::{AdamSettings, adam};
use super::gradient::Parameter;
use super::uncertainty::curvature_uncertainty;
use super::{Calibration, CalibrationProblem, ProxyParams, StageReport};
use crate::error::Result;
use crate::params::Mismatch;

/// One gradient stage: which parameters, their initial learning rates, the
/// schedule and the proxy it differentiates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GradientStage {
    pub name: String,
    pub parameters: Vec<Parameter>,
    pub adam: AdamSettings,
    pub proxy: ProxyParams,
}

/// Settings of the `paper` preset (defaults = the paper's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PaperPreset {
    pub stride: f64,
    /// The search box: |dx|, |dy| ≤ `shift_bound` px, |θ| ≤ `theta_bound`°.
    pub shift_bound: f64,
    pub theta_bound: f64,
    /// Coarse grid points along dx, dy, θ.
    pub coarse: [usize; 3],
    pub coarse_proxy: ProxyParams,
    /// How many coarse candidates the fine grids refine.
    pub refine_top: usize,
    /// Fine grid points along dx, dy, θ (spanning ± one coarse step).
    pub fine: [usize; 3],
    pub fine_proxy: ProxyParams,
    pub gradient_stages: Vec<GradientStage>,
    pub selection_proxy: ProxyParams,
    /// a1 candidates: `a1_count` values over [a1_range.0, a1_range.1].
    pub a1_range: (f64, f64),
    pub a1_count: usize,
    pub a1_proxy: ProxyParams,
}

impl Default for PaperPreset {
    fn default() -> Self {
        let proxy = |iterations, sigma| ProxyParams { iterations, sigma };
        let stage = |name: &str, parameters: Vec<Parameter>, steps, lr, lr_min, p| GradientStage {
            name: name.into(),
            parameters,
            adam: AdamSettings::new(steps, lr, lr_min),
            proxy: p,
        };
        use Parameter::{Dx, Dy, ThetaDeg};
        Self {
            stride: 2.0,
            shift_bound: 3.0,
            theta_bound: 1.0,
            coarse: [9, 9, 7],
            coarse_proxy: proxy(8, 0.7),
            refine_top: 5,
            fine: [5, 5, 3],
            fine_proxy: proxy(12, 0.7),
            gradient_stages: vec![
                stage(
                    "2A Adam dx",
                    vec![Dx],
                    50,
                    vec![0.05],
                    0.002,
                    proxy(12, 0.5),
                ),
                stage(
                    "2B Adam dy, θ",
                    vec![Dy, ThetaDeg],
                    60,
                    vec![0.03, 0.01],
                    0.001,
                    proxy(12, 1.0),
                ),
                stage(
                    "2C Adam dx, dy, θ",
                    vec![Dx, Dy, ThetaDeg],
                    80,
                    vec![0.01, 0.01, 0.005],
                    0.0005,
                    proxy(15, 0.7),
                ),
            ],
            selection_proxy: proxy(15, 0.7),
            a1_range: (1.90, 2.10),
            a1_count: 21,
            a1_proxy: proxy(12, 0.7),
        }
    }
}

/// `n` evenly spaced values over [lo, hi] (just `lo` when n = 1).
fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            if n == 1 {
                lo
            } else {
                lo + (hi - lo) * i as f64 / (n - 1) as f64
            }
        })
        .collect()
}

/// Runs the `paper` preset. `on_stage` sees each stage as it finishes.
pub fn calibrate_paper(
    problem: &CalibrationProblem<'_>,
    preset: &PaperPreset,
    on_stage: &mut dyn FnMut(&StageReport),
) -> Result<Calibration> {
    problem.validate()?;
    let t_all = Instant::now();
    let mut stages: Vec<StageReport> = Vec::new();
    let mut push = |r: StageReport| {
        on_stage(&r);
        stages.push(r);
    };
    let nominal = Mismatch::nominal(preset.stride);
    let (sb, tb) = (preset.shift_bound, preset.theta_bound);
    let pose = |dx: f64, dy: f64, theta_deg: f64| Mismatch {
        dx: dx.clamp(-sb, sb),
        dy: dy.clamp(-sb, sb),
        theta_deg: theta_deg.clamp(-tb, tb),
        ..nominal
    };
    let score = |m: &Mismatch, p: &ProxyParams| problem.score(m, p).unwrap_or(f64::INFINITY);

    // 0. coarse grid
    let t = Instant::now();
    let [nx, ny, nt] = preset.coarse;
    let mut coarse: Vec<(f64, Mismatch)> = Vec::with_capacity(nx * ny * nt);
    for &dx in &linspace(-sb, sb, nx) {
        for &dy in &linspace(-sb, sb, ny) {
            for &th in &linspace(-tb, tb, nt) {
                let m = pose(dx, dy, th);
                coarse.push((score(&m, &preset.coarse_proxy), m));
            }
        }
    }
    // stable: ties keep grid order
    coarse.sort_by(|a, b| a.0.total_cmp(&b.0));
    push(StageReport {
        name: "0 coarse grid".into(),
        evaluations: coarse.len(),
        seconds: t.elapsed().as_secs_f64(),
        parameters: coarse[0].1,
        score: coarse[0].0,
    });

    // 1. fine grids around the best coarse candidates, ± one coarse step
    let t = Instant::now();
    let step = |n: usize, bound: f64| {
        if n > 1 {
            2.0 * bound / (n - 1) as f64
        } else {
            0.0
        }
    };
    let (sx, sy, st) = (step(nx, sb), step(ny, sb), step(nt, tb));
    let [fx, fy, ft] = preset.fine;
    let mut grid_best = (f64::INFINITY, nominal);
    let mut evals = 0;
    for (_, c) in coarse.iter().take(preset.refine_top) {
        for &ox in &linspace(-sx, sx, fx) {
            for &oy in &linspace(-sy, sy, fy) {
                for &ot in &linspace(-st, st, ft) {
                    let m = pose(c.dx + ox, c.dy + oy, c.theta_deg + ot);
                    let s = score(&m, &preset.fine_proxy);
                    evals += 1;
                    if s < grid_best.0 {
                        grid_best = (s, m);
                    }
                }
            }
        }
    }
    push(StageReport {
        name: "1 fine grids".into(),
        evaluations: evals,
        seconds: t.elapsed().as_secs_f64(),
        parameters: grid_best.1,
        score: grid_best.0,
    });

    // 2. Adam stages, each from the previous one's last iterate
    let mut current = grid_best.1;
    for stage in &preset.gradient_stages {
        let t = Instant::now();
        let params = &stage.parameters;
        let at = |v: &[f64]| {
            let mut m = current;
            for (p, &x) in params.iter().zip(v) {
                p.set(&mut m, x);
            }
            m
        };
        let x0: Vec<f64> = params.iter().map(|p| p.get(&current)).collect();
        let (x, last) = adam(
            &x0,
            &stage.adam,
            |v| {
                problem
                    .score_and_gradient(&at(v), &stage.proxy, params)
                    .unwrap_or((f64::INFINITY, vec![0.0; params.len()]))
            },
            |v| {
                for (p, x) in params.iter().zip(v.iter_mut()) {
                    let bound = match p {
                        Parameter::Dx | Parameter::Dy => sb,
                        _ => tb,
                    };
                    *x = x.clamp(-bound, bound);
                }
            },
        );
        current = at(&x);
        push(StageReport {
            name: stage.name.clone(),
            evaluations: stage.adam.steps,
            seconds: t.elapsed().as_secs_f64(),
            parameters: current,
            score: last,
        });
    }

    // 3. grid-best vs gradient-best (the gradient result only if strictly lower)
    let t = Instant::now();
    let s_grid = score(&grid_best.1, &preset.selection_proxy);
    let s_grad = score(&current, &preset.selection_proxy);
    let (mut best, selected) = if s_grad < s_grid {
        (current, "gradient")
    } else {
        (grid_best.1, "grid")
    };
    push(StageReport {
        name: format!("3 selection ({selected})"),
        evaluations: 2,
        seconds: t.elapsed().as_secs_f64(),
        parameters: best,
        score: s_grid.min(s_grad),
    });

    // 4. a1
    let t = Instant::now();
    let mut best_a1 = (f64::INFINITY, best.a1);
    for a1 in linspace(preset.a1_range.0, preset.a1_range.1, preset.a1_count) {
        let s = score(&Mismatch { a1, ..best }, &preset.a1_proxy);
        if s < best_a1.0 {
            best_a1 = (s, a1);
        }
    }
    best.a1 = best_a1.1;
    push(StageReport {
        name: "4 dispersion a1".into(),
        evaluations: preset.a1_count,
        seconds: t.elapsed().as_secs_f64(),
        parameters: best,
        score: best_a1.0,
    });

    let final_score = score(&best, &preset.selection_proxy);
    let (uncertainty, uncertainty_evals) =
        curvature_uncertainty(problem, &best, final_score, &preset.selection_proxy);
    let nominal_score = score(&nominal, &preset.selection_proxy);
    let evaluations = stages.iter().map(|s| s.evaluations).sum::<usize>() + uncertainty_evals + 2;
    Ok(Calibration {
        preset: "paper".into(),
        model: problem.model,
        parameters: best,
        score: final_score,
        nominal_score,
        uncertainty,
        trade_offs: Vec::new(),
        stages,
        seconds: t_all.elapsed().as_secs_f64(),
        evaluations,
    })
}
