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

use serde::{Deserialize, Serialize};

use super::adam::{self, AdamSettings};
use super::gradient::Parameter;
use super::grid::{self, linspace};
use super::objective::Objective;
use super::stages::{Scored, StageRunner, lowest};
use super::uncertainty::curvature_uncertainty;
use super::{Calibration, CalibrationProblem, ProxyParams, StageReport, Uncertainty};
use crate::error::Result;
use crate::optics::BandSpread;
use crate::params::Mismatch;
use crate::params::Parameter::{A1, AlphaDeg, Dx, Dy, ThetaDeg};

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

/// The pose the grids search.
const POSE: [Parameter; 3] = [Dx, Dy, ThetaDeg];

/// `objective` held in the search box: |dx|, |dy| ≤ `shift_bound` px, the
/// angles within ±`theta_bound`°.
fn in_box(objective: Objective<'_>, shift_bound: f64, theta_bound: f64) -> Objective<'_> {
    let (sb, tb) = (shift_bound, theta_bound);
    objective
        .within(Dx, -sb, sb)
        .within(Dy, -sb, sb)
        .within(ThetaDeg, -tb, tb)
        .within(AlphaDeg, -tb, tb)
}

/// Runs the `paper` preset. `on_stage` sees each stage as it finishes.
pub fn calibrate_paper(
    problem: &CalibrationProblem<'_>,
    preset: &PaperPreset,
    on_stage: &mut dyn FnMut(&StageReport),
) -> Result<Calibration> {
    problem.validate()?;
    if problem.band_offsets().is_some() {
        super::Preset::Paper(preset.clone()).check_band_offsets()?;
    }
    super::Preset::Paper(preset.clone()).check_band_spread(problem.band_spread())?;
    if problem.model().samples_mask_per_band() {
        // its gradient stages differentiate a mask shared by every band
        return Err(crate::error::CassiError::Meaningless {
            what: "the paper preset with the dispersed-mask model".into(),
            reason: "its gradient stages need the rounded or subpixel model; \
                     calibrate the dispersed-mask model with the default preset"
                .into(),
        });
    }
    let mut run = StageRunner::new(on_stage);
    let coarse = coarse_grid(&mut run, problem, preset);
    let grid_best = fine_grids(&mut run, problem, preset, &coarse);
    let gradient_best = gradient_stages(&mut run, problem, preset, grid_best.parameters);
    let best = selection(
        &mut run,
        problem,
        preset,
        grid_best.parameters,
        gradient_best,
    );
    let best = a1_sweep(&mut run, problem, preset, best);

    let score = proxy_score(problem, &preset.selection_proxy);
    // a cancelled run's stages ended on failed scores: no result from them
    problem.check_cancelled()?;
    let final_score = score(&best);
    let (uncertainty, uncertainty_evals) =
        curvature_uncertainty(problem, &best, final_score, &preset.selection_proxy);
    let nominal_score = score(&Mismatch::nominal(preset.stride));
    let evaluations = run.evaluations() + uncertainty_evals + 2;
    let seconds = run.seconds();
    Ok(Calibration {
        preset: "paper".into(),
        model: problem.model(),
        parameters: best,
        score: final_score,
        nominal_score,
        uncertainty,
        interval_95: Uncertainty::default(),
        trade_offs: Vec::new(),
        uncertainty_fit: None,
        ridge_probes: None,
        model_blur_sigma_px: None,
        on_grid_margin_px: None,
        snapshots: None,
        band_offsets: None,
        band_spread: BandSpread::Point,
        stages: run.into_reports(),
        seconds,
        evaluations,
    })
}

/// The proxy score with `proxy` (∞ for an invalid ψ).
fn proxy_score<'a>(
    problem: &'a CalibrationProblem<'a>,
    proxy: &'a ProxyParams,
) -> impl Fn(&Mismatch) -> f64 + 'a {
    move |m| problem.score(m, proxy).unwrap_or(f64::INFINITY)
}

/// Stage 0, the coarse grid: every candidate, best first.
fn coarse_grid(
    run: &mut StageRunner<'_>,
    problem: &CalibrationProblem<'_>,
    preset: &PaperPreset,
) -> Vec<Scored> {
    let (sb, tb) = (preset.shift_bound, preset.theta_bound);
    let stage = run.start();
    let score = proxy_score(problem, &preset.coarse_proxy);
    let [nx, ny, nt] = preset.coarse;
    let axes = [
        linspace(-sb, sb, nx),
        linspace(-sb, sb, ny),
        linspace(-tb, tb, nt),
    ];
    let nominal = Mismatch::nominal(preset.stride);
    let objective = in_box(stage.objective(&score, nominal, &POSE), sb, tb);
    let mut coarse = grid::scan(&objective, &grid::product(&axes));
    // stable: ties keep grid order
    coarse.sort_by(|a, b| a.score.total_cmp(&b.score));
    run.finish(stage, "0 coarse grid", coarse[0]);
    coarse
}

/// Stage 1, fine grids around the best coarse candidates, ± one coarse step.
fn fine_grids(
    run: &mut StageRunner<'_>,
    problem: &CalibrationProblem<'_>,
    preset: &PaperPreset,
    coarse: &[Scored],
) -> Scored {
    let (sb, tb) = (preset.shift_bound, preset.theta_bound);
    let stage = run.start();
    let score = proxy_score(problem, &preset.fine_proxy);
    let step = |n: usize, bound: f64| {
        if n > 1 {
            2.0 * bound / (n - 1) as f64
        } else {
            0.0
        }
    };
    let [nx, ny, nt] = preset.coarse;
    let (sx, sy, st) = (step(nx, sb), step(ny, sb), step(nt, tb));
    let [fx, fy, ft] = preset.fine;
    let nominal = Mismatch::nominal(preset.stride);
    let objective = in_box(stage.objective(&score, nominal, &POSE), sb, tb);
    let around = |centre: f64, half: f64, n: usize| -> Vec<f64> {
        linspace(-half, half, n)
            .into_iter()
            .map(|o| centre + o)
            .collect()
    };
    let mut fine = Vec::new();
    for c in coarse.iter().take(preset.refine_top) {
        let c = c.parameters;
        let axes = [
            around(c.dx, sx, fx),
            around(c.dy, sy, fy),
            around(c.theta_deg, st, ft),
        ];
        fine.extend(grid::scan(&objective, &grid::product(&axes)));
    }
    let grid_best = lowest(&fine).unwrap_or(Scored::infinite(nominal));
    run.finish(stage, "1 fine grids", grid_best);
    grid_best
}

/// Stage 2, the Adam stages, each from the previous one's last iterate.
fn gradient_stages(
    run: &mut StageRunner<'_>,
    problem: &CalibrationProblem<'_>,
    preset: &PaperPreset,
    start: Mismatch,
) -> Mismatch {
    let mut current = start;
    for gradient_stage in &preset.gradient_stages {
        let stage = run.start();
        let proxy = &gradient_stage.proxy;
        let score_and_gradient = |m: &Mismatch, params: &[Parameter]| {
            problem
                .score_and_gradient(m, proxy, params)
                .unwrap_or((f64::INFINITY, vec![0.0; params.len()]))
        };
        let objective = in_box(
            stage.differentiable(&score_and_gradient, current, &gradient_stage.parameters),
            preset.shift_bound,
            preset.theta_bound,
        );
        let found = adam::minimise(&objective, &gradient_stage.adam);
        current = run.finish(stage, gradient_stage.name.clone(), found);
    }
    current
}

/// Stage 3, grid-best vs gradient-best (the gradient result only if
/// strictly lower).
fn selection(
    run: &mut StageRunner<'_>,
    problem: &CalibrationProblem<'_>,
    preset: &PaperPreset,
    grid_best: Mismatch,
    gradient_best: Mismatch,
) -> Mismatch {
    let stage = run.start();
    let score = proxy_score(problem, &preset.selection_proxy);
    let s_grid = stage.score(&score, &grid_best);
    let s_grad = stage.score(&score, &gradient_best);
    let (best, selected) = if s_grad < s_grid {
        (gradient_best, "gradient")
    } else {
        (grid_best, "grid")
    };
    let found = Scored {
        parameters: best,
        score: s_grid.min(s_grad),
    };
    run.finish(stage, format!("3 selection ({selected})"), found)
}

/// Stage 4, a1 over its candidates with the selected pose.
fn a1_sweep(
    run: &mut StageRunner<'_>,
    problem: &CalibrationProblem<'_>,
    preset: &PaperPreset,
    best: Mismatch,
) -> Mismatch {
    let stage = run.start();
    let score = proxy_score(problem, &preset.a1_proxy);
    let a1s: Vec<Vec<f64>> = linspace(preset.a1_range.0, preset.a1_range.1, preset.a1_count)
        .into_iter()
        .map(|a1| vec![a1])
        .collect();
    let scored = grid::scan(&stage.objective(&score, best, &[A1]), &a1s);
    let found = lowest(&scored).unwrap_or(Scored::infinite(best));
    run.finish(stage, "4 dispersion a1", found)
}
