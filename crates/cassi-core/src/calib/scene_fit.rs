//! The scene fit: variable projection with a coarse scene. For a candidate
//! instrument ψ the scene is not estimated once and held (the texture fit's
//! x̃, which carries the ψ it was reconstructed with) but solved for ψ
//! itself, in a basis too smooth to imitate the mask's code
//! (`coarse_scene.rs`), and ψ is scored by what that best scene leaves:
//!
//! ```text
//! score(ψ) = min_z ‖H y − H C A_ψ U z‖² / ‖H y‖²
//! ```
//!
//! U the coarse scene, A_ψ the model's operator (blur included), C the crop
//! (or zero pad) of its detector to the measurement's, H = I − G a linear
//! high-pass (G a Gaussian of [`SceneFitSettings::high_pass_px`], zero
//! outside the frame, so H is symmetric). H removes what every ψ explains
//! alike — the scene's slow light, which the band sum Σₖ Sₖ xₖ carries and
//! which made the least-squares solve converge slowly (after 200 CGLS
//! iterations 0.3 % above its limit without H) — and keeps the pixel-scale
//! code, which only the right ψ places and where the scene has least
//! detail the coarse basis misses.
//!
//! The minimum over z is a linear least-squares problem (CGLS,
//! warm-started from the last candidate's z). ψ moves by BFGS with a
//! backtracking line search: the gradient is 2 Jᵀr / ‖H y‖² with J = −H C
//! (∂A/∂ψ) U z taken with z held, by forward differences — exact, as r ⊥
//! range(H C A U) at the solved z (the variable-projection identity; tested
//! against the score's own finite differences) — and the curvature starts
//! from JᵀJ, with the direction z absorbs outright (the scene's overall
//! brightness, H C A U z itself) projected out of each column.
//!
//! Why: the texture fit's error budget (benchmark `--limits`) showed its
//! scene estimate, not its model, setting the error: dx RMSE 0.34 px blind
//! against 0.04 px with the true scene; the proxy's x̃ keeps the imprint of
//! the ψ it was made with, and a fit with x̃ held cannot leave it.

use serde::{Deserialize, Serialize};

use super::coarse_scene::{CoarseRows, CoarseScene};
use super::detail_pass::DetailPass;
use super::nominal_start::NominalStart;
use super::quasi_newton::{LeastSquares, minimise};
use super::residual_weights::ResidualWeighting;
use super::spectral_basis::SpectralBasis;
use super::{CalibrationProblem, reframe};
use crate::cube::Cube;
use crate::error::Result;
use crate::linop::LinearOperator;
use crate::optics::ModelOperator;
use crate::optics::blur::GaussianBlur;
use crate::params::{Mismatch, Parameter};
use crate::solvers::{CglsParams, CglsScratch, Silent, cgls};

/// Settings of the scene fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SceneFitSettings {
    /// Spacing of the coarse scene's nodes, pixels.
    pub cell_px: usize,
    /// Spectral nodes of the coarse scene (piecewise linear in band
    /// index; the band count or more: every band free). 6 by default: a
    /// scene with more spectral freedom absorbs part of a dispersion
    /// mismatch (band k's code moved by (a1 − a1*)·k trades against dx,
    /// α against dy), and the blind fit slides along those ridges. Tuning
    /// half, 45 cases (`calibrate_physical_tuning_scene_nodes{4,6,14}.json`
    /// against the 10 nodes before, the stage before the blur pass in
    /// `…_tuning_blur_pass.json`): random poses dx RMSE 0.050 / 0.046 /
    /// 0.155 / 0.153 px for 4 / 6 / 10 / 14 nodes, a1 0.0023 / 0.0018 /
    /// 0.0059 / 0.0061, α 0.040 / 0.045 / 0.063 / 0.074°; all six within
    /// tolerance 22 / 26 / 25 / 20 of 45 (4 nodes let an aligned case
    /// slide 0.28 px in dx).
    pub spectral_nodes: usize,
    /// σ of the Gaussian the high-pass subtracts, pixels.
    pub high_pass_px: f64,
    /// The first solve, from z = 0.
    pub cold_solve: CglsParams,
    /// Every later solve, from the last accepted z.
    pub warm_solve: CglsParams,
    /// BFGS steps at most.
    pub max_steps: usize,
    /// A second pass over the pose and dispersion on a finer, ridge-regularised scene
    /// (on by default: see [`FinePass`]). `None`: the first pass alone, as
    /// in settings written before the pass existed (which read back
    /// without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fine_pass: Option<FinePass>,
    /// Between the two: the first pass refitted on its scene times the
    /// scene's texture ([`DetailPass`]; on by default). `None` (off) in
    /// settings written before it existed, which read back without it, as
    /// they ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detail_pass: Option<DetailPass>,
    /// The first pass run again from the nominal dispersion ([`NominalStart`];
    /// on by default). `None` (off) in settings written before it existed,
    /// which read back without it, as they ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal_start: Option<NominalStart>,
    /// The first pass's scene held near the scene solved at its start by a
    /// ridge λ‖z − z_start‖² (λ = this × K's mean squared column norm), so
    /// that moving the dispersion cannot dim the dark bands' scene to
    /// hide their code's drift (the blind errors pivot on the bright end's
    /// band, stop 65). A probe, not adopted: on the tuning half's 30 random
    /// poses (`bench/results/default_stop65/pivot/fpr*.json`) the first
    /// pass still pivots on band 23.1 (ridge 0.01) and 21.7 (0.1) against
    /// 23.8, and the later passes end where they did (dx within 16 of 30
    /// each; all six 12 → 11 and 9). `None` (the default, and settings
    /// written before the field): no ridge.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_pass_ridge: Option<f64>,
}

/// The scene fit's second pass, on by default: from the
/// first pass's answer, the parameters of `free` refitted (by default dx,
/// dy, θ, a1 and α, with σ held), the
/// scene on `cell_px` nodes with a ridge penalty λ‖z − z₀‖² in the score
/// (λ = `ridge` × the mean squared column norm of K at the pass's start;
/// z₀ per [`RidgeAnchor`]). Why: on aligned instruments the 8-px scene
/// leaves textured scenes' detail unexplained and the fit slides 0.2–0.4
/// px along dx (`bench/results/scene_fit_scan.json`); in probes on the
/// tuning half a 4-px scene solved to convergence kept the same bias, and
/// one stopped early (60 CGLS iterations from zero) removed it — the ridge
/// makes that early stop explicit, so the answer does not hang on an
/// iteration count. Tuned on the tuning half
/// (`calibrate_physical_tuning_fine_pass*.json`), where its own floors were
/// derived (`Fit::SceneFinePass`); reported on the held-out half
/// (`calibrate_physical_held_out.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FinePass {
    /// Spacing of its scene's nodes, pixels.
    pub cell_px: usize,
    /// The ridge weight, relative to K's mean squared column norm.
    pub ridge: f64,
    /// What the ridge pulls the scene toward.
    pub anchor: RidgeAnchor,
    /// Which parameters it refits. Settings written before this field
    /// read back with the pose and slope, as they ran.
    #[serde(default = "FinePassFree::before_the_field")]
    pub free: FinePassFree,
    /// Its first solve, from the first pass's scene refined onto its nodes.
    pub first_solve: CglsParams,
    /// BFGS steps at most.
    pub max_steps: usize,
    /// Its scene multiplied by the detail pass's map too (x_k = d ⊙ (U z)_k
    /// on its finer nodes), when the detail pass ran; otherwise (the
    /// default, and settings written before the field) its scene is smooth
    /// between the nodes. A probe, not adopted: tuning half, 45 cases
    /// (`calibrate_physical_tuning_stop49/fine_detail.json`), all six
    /// within tolerance 29 → 30, but aligned beads slid to dx +0.19 px
    /// and random dx RMSE rose 0.042 → 0.047 px.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub carries_detail: bool,
    /// Its residual weighted by the local energy of what the pass before it
    /// left ([`ResidualWeighting`]), held through the pass; `None` (the
    /// default, and settings written before the field): unweighted. A
    /// probe, not adopted: tuning half, window 3 px, floor quantile 0.25
    /// (`…_stop49/fine_weighted.json`), all six 29 → 28 of 45, aligned dx
    /// RMSE 0.012 → 0.053 px.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weighting: Option<ResidualWeighting>,
    /// Its scene's spectral nodes; `None` (the default, and settings
    /// written before the field): the first pass's. A probe, not adopted:
    /// the first pass's 6 nodes, told the true scene through them, bias dx
    /// and a1 along their ridge on scenes with sharp spectra (stop 58,
    /// held-out round 32: peppers dx −0.060 px, a1 +0.0057; with 10 nodes
    /// −0.012, +0.0014); 10 nodes here took the tuning half 15 → 18 of 25
    /// but fresh round 35 22 → 17 of 35 — aligned 10 → 14 of 15, random
    /// poses 12 → 3 of 20, sliding along dx–a1
    /// (`bench/results/default_band_spread_stop58/`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectral_nodes: Option<usize>,
    /// Its scene's spectral nodes where the on-grid run
    /// ([`Self::on_grid`]) does not take its place, which keeps its own;
    /// `None` (the default, and settings written before the field): the
    /// first pass's. [`Self::spectral_nodes`], when set, wins. A probe
    /// (stop 66): the first and detail passes on fewer nodes than this one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub off_grid_nodes: Option<usize>,
    /// The pass again on more spectral nodes where it ends with the mask on
    /// the pixel grid ([`OnGridNodes`]); `None` (settings written before
    /// the field): never. [`Self::spectral_nodes`], when set, wins.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub on_grid: Option<OnGridNodes>,
    /// σ of its high-pass's Gaussian, pixels; `None` (the default, and
    /// settings written before the field): the first pass's
    /// [`SceneFitSettings::high_pass_px`]. A probe, not adopted: a wider one
    /// lets the band light's slow ramps in, and the coarse scene's slow
    /// errors with them — tuning half's 30 random poses, all six 9 → 8
    /// (1 px) and 7 (4 px), dx sliding further along dx–a1
    /// (`bench/results/default_stop60/`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub high_pass_px: Option<f64>,
    /// Its scene's spectra the principal spectra of GAP-TV's reconstruction
    /// at its start ([`SpectralBasis`]) instead of evenly spaced nodes;
    /// `None` (the default, and settings written before the field): nodes.
    /// [`Self::spectral_nodes`], when set, wins. A probe, not adopted: 6
    /// principal spectra, tuning half's 30 random poses, all six 9 → 10,
    /// dx within 16 → 16, dx moving both ways (`bench/results/default_stop60/`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectral_basis: Option<SpectralBasis>,
    /// Its run off the pixel grid (the first run, a random pose's answer)
    /// with scene solves and a free set of its own ([`OffGridRun`]; on by
    /// default since stop 72); the on-grid run keeps the pass's. `None`
    /// (settings written before the field, as they ran): the pass's own in
    /// both runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub off_grid_run: Option<OffGridRun>,
}

/// The fine pass's run off the pixel grid with its own warm solves and free
/// set; by default 60 CGLS iterations per warm solve and dx, θ and a1
/// refitted (dy and α stay the detail pass's). Why: that run's BFGS scores
/// each trial with a warm solve from the last scene and takes its Jacobian
/// with the scene held, so the default's 20 iterations let the scene lag
/// the pose and hold the answer near the pass's start, the first pass's,
/// whose dx reads low (stop 71's ridge scans); solved further, free dy and
/// α slide along their ridge (stop 71: all six 12 → 10 of 30). Tuning
/// half, three seed rounds, 90 random poses
/// (`bench/results/default_stop72/tuning_rounds/`): dx RMSE 0.162 → 0.105
/// px (lower in each round), a1 0.0060 → 0.0040, mean dx error −0.037 →
/// −0.018 px, the worst 0.849 → 0.400 px, all six 33 → 34, geometry 40 →
/// 42; the aligned instruments (the on-grid run) unchanged, 43 of 45. The
/// count is a wash: a fourth tuning round run after the choice 13 → 11
/// (`…/tuning_rounds/round3/`), and held out (fresh rounds 56–58, 60
/// random poses beside the default before) 24 → 24, dx RMSE 0.075 → 0.065
/// px but dy 0.039 → 0.047 and α 0.053 → 0.067° (a pose now and then left
/// where the detail pass put dy and α).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OffGridRun {
    /// Every solve after its first, from the last accepted scene.
    pub warm_solve: CglsParams,
    /// The parameters it refits.
    pub free: FinePassFree,
    /// Then the pass's own free set refitted from its answer and scene,
    /// with the pass's own warm solves (dy and α freed again after dx, θ
    /// and a1 settle). `false` (the default, and settings written before
    /// the field): its answer is the run's. A probe, not adopted (stop 72;
    /// tuning half, three seed rounds, 90 random poses,
    /// `bench/results/default_stop72/tuning_rounds/then_the_pass/`): against
    /// the run alone, geometry within 42 → 43, dy 79 → 81, α 79 → 81, but σ
    /// 74 → 70 (the blur pass reads it at the moved geometry) and all six
    /// 34 → 31, the RMSEs the same (dx 0.105 px), one more BFGS run.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub then_the_pass: bool,
    /// What that refit after the run frees (set, it implies the refit, so
    /// no setting names a free set that never runs); `None` (and settings
    /// written before the field, as they ran): the pass's own free set,
    /// where [`Self::then_the_pass`] asks for the refit. A probe,
    /// not adopted (stop 73): [`FinePassFree::DyAndAlpha`], only what the
    /// run held, dx, θ and a1 left bitwise the run's — tuning half, four
    /// seed rounds, 120 random poses
    /// (`bench/results/default_stop73/dy_alpha_probe/`): dy within 106 →
    /// 108, α 106 → 108, geometry 58 → 58, σ 97 → 96, all six 45 → 44;
    /// the σ flips are the blur pass's small-σ reads moving up to 0.075 px
    /// where dy and α moved under 0.002 px (`sigma_moves.txt`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub then_free: Option<FinePassFree>,
}

impl Default for OffGridRun {
    fn default() -> Self {
        Self {
            warm_solve: CglsParams {
                iterations: 60,
                tolerance: 1e-5,
            },
            free: FinePassFree::PoseAndSlope,
            then_the_pass: false,
            then_free: None,
        }
    }
}

/// The fine pass run again from its start with its scene on
/// `spectral_nodes` spectral nodes where its answer on the first pass's
/// nodes lands within `below_phase` of the pixel grid
/// ([`grid_phase`](super::grid_phase): 0 on it, ≈ 1 for a rotated mask or
/// a non-integer stride); that answer is the pass's. Why: on the grid the
/// first pass's 6 nodes bias dx along dx–a1 on scenes with sharp spectra
/// (the scene told through them, stop 58: −0.06 px; through 10, −0.01),
/// and 10 nodes remove it — the tuning half's aligned cases 11 → 14 of 15
/// (cd, beads, chart: dx +0.07…+0.11 px → within 0.007) — while off the
/// grid the same 10 nodes let the answer slide along dx–a1 and dy–α
/// (held-out round 35's random poses 12 → 3 of 20;
/// `bench/results/default_band_spread_stop58/`). Judged at the pass's
/// answer, not its start: there the tuning half's aligned instruments lie
/// at phase 0.01–0.28 and its random poses at 0.99–1.29 (at the start,
/// the detail pass's answer, aligned ones reach 0.98).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OnGridNodes {
    pub spectral_nodes: usize,
    pub below_phase: f64,
    /// Run again from the first run's answer and scene (on the new nodes)
    /// instead of from the first run's start; the objective is the same
    /// (the ridge still anchored on the first pass's scene). `false` in
    /// settings written before the field, as they ran, and by default: a
    /// probe, not adopted — a quarter fewer scores in that run, but the
    /// tuning half's aligned instruments 14 → 13 of 15 (beads stays in the
    /// first run's minimum, dx +0.100 px; `bench/results/default_stop60/`).
    #[serde(default)]
    pub from_first_answer: bool,
    /// Where the pass's start (the detail pass's answer) already lies below
    /// this grid phase, the run on the first pass's nodes — whose answer
    /// here only judges the phase — is left out and the on-grid run goes
    /// straight from the start: the same answer wherever that run would
    /// have ended below [`Self::below_phase`] too. `None` (settings written
    /// before the field, and with [`Self::from_first_answer`]): judged at
    /// the answer always. Why: the judging run is a third of an aligned
    /// instrument's fine pass. Chosen on the tuning half (stop 63,
    /// `bench/results/default_stop63/phase_at_start/`): its aligned
    /// instruments start at phase 0.06–0.98 (8 of 15 below 0.5) and end at
    /// 0.01–0.28; its random poses start at 0.86–1.30 — 0.5 leaves 0.35 to
    /// the nearest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub judged_at_start_below: Option<f64>,
}

impl Default for OnGridNodes {
    fn default() -> Self {
        Self {
            spectral_nodes: 10,
            below_phase: 0.5,
            from_first_answer: false,
            judged_at_start_below: Some(0.5),
        }
    }
}

/// z₀ of the fine pass's ridge λ‖z − z₀‖².
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RidgeAnchor {
    /// z₀ = 0. Tuning half, ridge 0.03: aligned dx RMSE 0.258 → 0.007 px,
    /// θ 0.029 → 0.004°, a1 0.0066 → 0.0002, but random poses slid along
    /// the dx–a1 ridge (one by 0.58 px; all six within tolerance 12 → 9
    /// of 30): the penalty on the scene's size depends on ψ.
    Zero,
    /// z₀ = the first pass's scene on the fine nodes: only the detail it
    /// adds is penalised. Tuning half (45 random + aligned cases; without
    /// the pass: aligned dx RMSE 0.258 px, θ 0.029°, a1 0.0066; random dx
    /// 0.171, θ 0.017°, a1 0.0064; all six within tolerance 17), ridge
    /// 0.1 / 0.03 / 0.01 / 0.003: aligned dx 0.184 / 0.104 / 0.015 / 0.043
    /// px, θ 0.023 / 0.013 / 0.004 / 0.006°, a1 0.0051 / 0.0034 / 0.0006 /
    /// 0.0018; random dx 0.144 / 0.138 / 0.165 / 0.169, θ 0.014 / 0.013 /
    /// 0.013 / 0.014°, a1 0.0053 / 0.0052 / 0.0062 / 0.0063, no slide; all
    /// within 18 / 19 / 20 / 20.
    FirstPassScene,
}

/// The parameters the fine pass refits (those of them the preset fits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FinePassFree {
    /// dx, θ and a1; dy, α and σ stay the first pass's. Tuning half:
    /// aligned dx RMSE 0.258 → 0.015 px (`…_fine_pass_r0.01.json`). With
    /// the ridge toward zero (a probe, not recorded) freeing dy and α too
    /// let them slide along their ridge on random poses. Its stated errors
    /// use the floors derived for `Geometry` (the default). Since stop 72
    /// the default's off-grid run's ([`OffGridRun`]), its scene solved
    /// further.
    PoseAndSlope,
    /// dx, dy, θ, a1 and α; σ stays the first pass's. The default (since
    /// stop 72 the on-grid run's; the off-grid run has its own). Tuning
    /// half, four configurations (`…_fine_pass_geometry*.json` against
    /// `PoseAndSlope`'s): aligned dy RMSE 0.069–0.174 → 0.017–0.109 px, α
    /// 0.103–0.235 → 0.028–0.148°, all six within tolerance 69 → 77 of
    /// 180 (no configuration lost: 23 / 17 / 21 / 16 against 20 / 15 / 18
    /// / 16); aligned dx 0.015 → 0.047 px on the first configuration (the
    /// price), 0.100 → 0.006 on the third.
    Geometry,
    /// All six, the blur σ too — measured and rejected, kept so its record
    /// reproduces: on the tuning half's first configuration
    /// (`…_fine_pass_all.json`) σ collapses toward zero (error −0.33 px on
    /// average; the ridge holds the finer scene near the first pass's, and
    /// a sharper model buys back the detail), all six within tolerance
    /// 23 → 1 of 45, 8.6 s per case. Why σ stays the first pass's.
    All,
    /// The geometry and the dispersion's curvature a2 (band k at a1·k +
    /// a2·k²): the geometry refitted first with a2 held at the preset's
    /// value (0 unless given), then all six from there, so the curved
    /// answer never scores above the straight one; σ stays the first
    /// pass's. For a prism whose dispersion is not linear in the band
    /// index. A local refinement: on an instrument curved by −0.012
    /// px/band² it reaches the truth from −0.010 in 21 of 35 held-out cases,
    /// from −0.006 in 7 of 45 tuning cases (31 stay within 0.001 of their
    /// start: the straight fit's basin places the red bands elsewhere).
    /// The stated errors of the other five are the two passes' with a2
    /// marginalised out of the fine block, a1's with a2's floor carried
    /// along their ridge; a2's own is the fine pass's block sandwich with
    /// its floors ([`super::model_error_floor`]).
    GeometryAndCurvature,
    /// dy and α alone, the code's shift and the dispersion's tilt across
    /// the rows: for a refit after a run that held them
    /// ([`OffGridRun::then_free`]), dx, θ and a1 left where that run put
    /// them. A probe (stop 73; not adopted: [`OffGridRun::then_free`]).
    DyAndAlpha,
}

impl FinePassFree {
    pub const ALL: [FinePassFree; 5] = [
        FinePassFree::PoseAndSlope,
        FinePassFree::Geometry,
        FinePassFree::All,
        FinePassFree::GeometryAndCurvature,
        FinePassFree::DyAndAlpha,
    ];

    /// The name in settings files and on command lines.
    pub fn key(self) -> &'static str {
        match self {
            FinePassFree::PoseAndSlope => "pose-and-slope",
            FinePassFree::Geometry => "geometry",
            FinePassFree::All => "all",
            FinePassFree::GeometryAndCurvature => "geometry-and-curvature",
            FinePassFree::DyAndAlpha => "dy-and-alpha",
        }
    }

    /// What settings written before [`FinePass::free`] existed ran.
    fn before_the_field() -> Self {
        FinePassFree::PoseAndSlope
    }

    /// The parameters it names.
    pub fn parameters(self) -> &'static [Parameter] {
        use Parameter::*;
        match self {
            FinePassFree::PoseAndSlope => &[Dx, ThetaDeg, A1],
            FinePassFree::Geometry => &[Dx, Dy, ThetaDeg, A1, AlphaDeg],
            FinePassFree::All => &Parameter::CALIBRATED,
            FinePassFree::GeometryAndCurvature => &[Dx, Dy, ThetaDeg, A1, AlphaDeg, A2],
            FinePassFree::DyAndAlpha => &[Dy, AlphaDeg],
        }
    }
}

impl std::str::FromStr for FinePassFree {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        by_key(s, &FinePassFree::ALL, FinePassFree::key)
    }
}

/// The one of `all` whose `key` is `s`, or an error naming them all.
pub(super) fn by_key<T: Copy>(
    s: &str,
    all: &[T],
    key: fn(T) -> &'static str,
) -> std::result::Result<T, String> {
    all.iter().copied().find(|&a| key(a) == s).ok_or_else(|| {
        let keys: Vec<&str> = all.iter().map(|&a| key(a)).collect();
        format!("'{s}': expected one of {}", keys.join(", "))
    })
}

impl RidgeAnchor {
    pub const ALL: [RidgeAnchor; 2] = [RidgeAnchor::Zero, RidgeAnchor::FirstPassScene];

    /// The name in settings files and on command lines.
    pub fn key(self) -> &'static str {
        match self {
            RidgeAnchor::Zero => "zero",
            RidgeAnchor::FirstPassScene => "first-pass-scene",
        }
    }
}

impl std::str::FromStr for RidgeAnchor {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        by_key(s, &RidgeAnchor::ALL, RidgeAnchor::key)
    }
}

impl Default for FinePass {
    fn default() -> Self {
        Self {
            cell_px: 4,
            ridge: 0.01,
            anchor: RidgeAnchor::FirstPassScene,
            free: FinePassFree::Geometry,
            first_solve: CglsParams {
                iterations: 150,
                tolerance: 1e-5,
            },
            max_steps: 20,
            carries_detail: false,
            weighting: None,
            spectral_nodes: None,
            off_grid_nodes: None,
            on_grid: Some(OnGridNodes::default()),
            high_pass_px: None,
            spectral_basis: None,
            off_grid_run: Some(OffGridRun::default()),
        }
    }
}

impl SceneFitSettings {
    /// Its first pass's ridge (a settings file's, say), named when not a
    /// positive finite weight: before any stage runs.
    pub(crate) fn check_first_pass_ridge(&self) -> Result<()> {
        match self.first_pass_ridge {
            Some(r) if !(r.is_finite() && r > 0.0) => {
                Err(crate::error::CassiError::InvalidParameter {
                    name: "scene_fit.first_pass_ridge",
                    value: r,
                    reason: "the first pass's ridge weight: positive and finite".into(),
                })
            }
            _ => Ok(()),
        }
    }
}

impl FinePass {
    /// Its probes' settings for a cube of `bands` bands, named when out of
    /// range (a settings file's, say): before any stage runs.
    pub(crate) fn check(&self, bands: usize) -> Result<()> {
        if let Some(px) = self.high_pass_px
            && !(px.is_finite() && (0.0..=crate::params::MAX_BLUR_SIGMA_PX).contains(&px))
        {
            return Err(crate::error::CassiError::InvalidParameter {
                name: "fine_pass.high_pass_px",
                value: px,
                reason: format!(
                    "the fine pass's high-pass width, pixels: 0 to {}",
                    crate::params::MAX_BLUR_SIGMA_PX
                ),
            });
        }
        match self.spectral_basis {
            Some(basis) => basis.check(bands),
            None => Ok(()),
        }
    }

    /// The pass to run again after an answer at grid phase `phase`
    /// ([`grid_phase`](super::grid_phase)), if any: on its [`OnGridNodes`]'
    /// spectral nodes below their phase.
    pub(crate) fn again_at(&self, phase: f64) -> Option<Self> {
        let on_grid = self.on_grid?;
        (phase < on_grid.below_phase)
            .then(|| self.on_grid_run(on_grid))
            .flatten()
    }

    /// This pass on `on_grid`'s spectral nodes, unless its own nodes are
    /// set outright (a probe's, which win).
    fn on_grid_run(&self, on_grid: OnGridNodes) -> Option<Self> {
        self.spectral_nodes.is_none().then_some(Self {
            spectral_nodes: Some(on_grid.spectral_nodes),
            off_grid_run: None,
            ..*self
        })
    }

    /// The parameters this run refits: its [`OffGridRun`]'s where it has
    /// one, the pass's otherwise.
    pub(crate) fn run_free(&self) -> FinePassFree {
        self.off_grid_run.map_or(self.free, |run| run.free)
    }

    /// The refit after this run's own, if any ([`OffGridRun::then_the_pass`]):
    /// the pass without its off-grid run, whose warm solves that refit
    /// takes, and whose free set unless [`OffGridRun::then_free`] names one.
    pub(crate) fn then(&self) -> Option<Self> {
        self.off_grid_run
            .filter(|run| run.then_the_pass || run.then_free.is_some())
            .map(|run| Self {
                off_grid_run: None,
                free: run.then_free.unwrap_or(self.free),
                ..*self
            })
    }

    /// The parameters this run's answer was last refitted over (the fit
    /// its stated errors' fine block comes from).
    pub(crate) fn answer_free(&self) -> FinePassFree {
        self.then().map_or(self.run_free(), |then| then.free)
    }

    /// The pass to run in place of this one where its start lies at grid
    /// phase `start_phase`, if any: the on-grid run, below
    /// [`OnGridNodes::judged_at_start_below`] (never with
    /// [`OnGridNodes::from_first_answer`], which starts from this run's
    /// answer).
    pub(crate) fn again_from_start(&self, start_phase: f64) -> Option<Self> {
        let on_grid = self.on_grid?;
        let below = on_grid.judged_at_start_below?;
        (!on_grid.from_first_answer && start_phase < below)
            .then(|| self.on_grid_run(on_grid))
            .flatten()
    }

    /// Its scene's spectral nodes after a first pass on `first_pass_nodes`.
    fn nodes_after(&self, first_pass_nodes: usize) -> usize {
        self.spectral_nodes
            .or(self.off_grid_nodes)
            .unwrap_or(first_pass_nodes)
    }

    /// The pass's scene fit (`settings` with its nodes, first solve and
    /// steps), started from `first`, a solve of the first pass's fit
    /// `coarse`: that scene refined onto the pass's nodes (returned with
    /// it, the pass's first solve starts there), times `detail` where
    /// given, the ridge anchored as [`Self::anchor`] says, the residual
    /// weighted from `first`'s where [`Self::weighting`] says.
    pub(crate) fn scene_fit<'a>(
        &self,
        problem: &'a CalibrationProblem<'a>,
        settings: SceneFitSettings,
        (coarse, first): (&SceneFit<'_>, &Solved),
        detail: Option<Vec<f32>>,
    ) -> Result<(SceneFit<'a>, Vec<f32>)> {
        let fine_settings = SceneFitSettings {
            cell_px: self.cell_px,
            spectral_nodes: self.nodes_after(settings.spectral_nodes),
            high_pass_px: self.high_pass_px.unwrap_or(settings.high_pass_px),
            cold_solve: self.first_solve,
            warm_solve: self
                .off_grid_run
                .map_or(settings.warm_solve, |run| run.warm_solve),
            max_steps: self.max_steps,
            fine_pass: None,
            ..settings
        };
        let mut fine = SceneFit::new(problem, fine_settings)?;
        if let (None, Some(basis)) = (self.spectral_nodes, self.spectral_basis) {
            let spectra = basis.spectra(problem, &first.psi)?;
            fine = fine.with_spectra(&spectra, basis.components);
        }
        // the smooth factor's nodes either way: `coarse` is the plain basis
        let scene = fine.coefficients_from(coarse, &first.z);
        if let Some(map) = detail {
            fine = fine.with_detail(map);
        }
        let anchor = match self.anchor {
            RidgeAnchor::Zero => None,
            RidgeAnchor::FirstPassScene => Some(scene.clone()),
        };
        let mut fine = fine.with_ridge(self.ridge, anchor);
        if let Some(weighting) = &self.weighting {
            fine = fine.with_weights(weighting, first)?;
        }
        Ok((fine, scene))
    }
}

impl SceneFitSettings {
    /// These settings with the first pass alone (the detail and fine
    /// passes off): the objective scans and choices score with.
    pub fn first_pass_only(self) -> Self {
        Self {
            detail_pass: None,
            fine_pass: None,
            nominal_start: None,
            ..self
        }
    }
}

impl Default for SceneFitSettings {
    fn default() -> Self {
        Self {
            cell_px: 8,
            spectral_nodes: 6,
            high_pass_px: 0.5,
            cold_solve: CglsParams {
                iterations: 60,
                tolerance: 1e-5,
            },
            warm_solve: CglsParams {
                iterations: 20,
                tolerance: 1e-5,
            },
            max_steps: 20,
            fine_pass: Some(FinePass::default()),
            detail_pass: Some(DetailPass::default()),
            nominal_start: Some(NominalStart::default()),
            first_pass_ridge: None,
        }
    }
}

/// Forward-difference step of the Jacobian, and the step below which the
/// fit counts a parameter as settled, per parameter.
fn difference_step(p: Parameter) -> f64 {
    match p {
        Parameter::Dx | Parameter::Dy | Parameter::BlurSigmaPx => 0.01,
        Parameter::ThetaDeg => 0.005,
        Parameter::A1 => 0.0005,
        Parameter::A2 => 0.00002,
        Parameter::AlphaDeg => 0.01,
    }
}

/// Forward-difference step of a band shift's Jacobian column, pixels (dx's).
pub(crate) const BAND_SHIFT_STEP: f64 = 0.01;

/// `base`'s instrument with band k landing `along[k]` px further along the
/// dispersion: as `base` with its mask moved `along[0]` along the
/// dispersion (direction α) and the other bands shifted relative to band 0.
/// Why: a common shift of every band is that move (the scene, free,
/// follows the light), and the operator's columns start where band 0
/// lands, so band 0 is never shifted itself.
pub(crate) fn shifted_instrument(base: &Mismatch, along: &[f64]) -> (Mismatch, Vec<f64>) {
    let common = along.first().copied().unwrap_or(0.0);
    let alpha = base.alpha_deg.to_radians();
    let psi = Mismatch {
        dx: base.dx + common * alpha.cos(),
        dy: base.dy + common * alpha.sin(),
        ..*base
    };
    (psi, along.iter().map(|d| d - common).collect())
}

pub(super) fn settled_step(p: Parameter) -> f64 {
    difference_step(p) / 5.0
}

/// K_ψ = H C A_ψ U: coarse-scene coefficients → the high-passed frame.
struct SceneOperator<'f> {
    fit: &'f SceneFit<'f>,
    op: ModelOperator,
}

/// Buffers of one [`SceneOperator`] application, per thread.
#[derive(Default)]
struct OperatorScratch {
    /// The bands' coarse images (bands × node plane).
    images: Vec<f32>,
    detector: Vec<f32>,
    frame: Vec<f32>,
    tmp: Vec<f32>,
    /// The residual times √w (a weighted fit's adjoint).
    weighted: Vec<f32>,
}

thread_local! {
    static OPERATOR_SCRATCH: std::cell::RefCell<OperatorScratch> = std::cell::RefCell::default();
}

impl SceneOperator<'_> {
    /// out ← H C A_ψ U z, U z given by its bands' coarse images: the
    /// scene made a row at a time inside the CASSI product, never stored
    /// (the stored cube's writing and reading cost as much as the product).
    fn frame_of_images(&self, images: &[f32], out: &mut [f32], s: &mut OperatorScratch) {
        let (rows, det) = self.op.measurement_shape();
        let cols = self.fit.cols();
        s.detector.resize(rows * det, 0.0);
        let scene = CoarseRows {
            basis: &self.fit.basis,
            images,
        };
        self.op.apply_rows(&scene, &mut s.detector);
        reframe(&s.detector, det, &mut s.frame, cols);
        self.fit.high_pass(&s.frame, out, &mut s.tmp);
        self.fit.weigh(out);
    }
}

impl LinearOperator for SceneOperator<'_> {
    fn domain_len(&self) -> usize {
        self.fit.basis.domain_len()
    }

    fn range_len(&self) -> usize {
        self.fit.data.len()
    }

    fn apply(&self, z: &[f32], out: &mut [f32]) {
        crate::scratch::with_taken(&OPERATOR_SCRATCH, |s| {
            let mut images = std::mem::take(&mut s.images);
            self.fit.basis.band_images(z, &mut images);
            self.frame_of_images(&images, out, s);
            s.images = images;
        })
    }

    fn adjoint(&self, r: &[f32], z: &mut [f32]) {
        crate::scratch::with_taken(&OPERATOR_SCRATCH, |s| {
            let (rows, det) = self.op.measurement_shape();
            let cols = self.fit.cols();
            s.frame.resize(rows * cols, 0.0);
            // Kᵀ = Uᵀ Aᵀ Cᵀ H √w: the weights first
            let r = match &self.fit.root_weights {
                Some(w) => {
                    s.weighted.clear();
                    s.weighted.extend(r.iter().zip(w).map(|(&r, &w)| r * w));
                    &s.weighted[..]
                }
                None => r,
            };
            self.fit.high_pass(r, &mut s.frame, &mut s.tmp);
            reframe(&s.frame, cols, &mut s.detector, det);
            let images = &mut s.images;
            self.op.with_adjoint_rows(&s.detector, |row| {
                self.fit.basis.adjoint_rows(row, images, z)
            });
        })
    }
}

/// [K; √λ I]: the least-squares problem of a ridge-penalised scene,
/// min_z ‖H y − K z‖² + λ‖z‖², as one stacked operator for CGLS.
struct WithRidge<'k, 'f> {
    k: &'k SceneOperator<'f>,
    root_lambda: f32,
}

impl LinearOperator for WithRidge<'_, '_> {
    fn domain_len(&self) -> usize {
        self.k.domain_len()
    }

    fn range_len(&self) -> usize {
        self.k.range_len() + self.k.domain_len()
    }

    fn apply(&self, z: &[f32], out: &mut [f32]) {
        let (head, tail) = out.split_at_mut(self.k.range_len());
        self.k.apply(z, head);
        tail.iter_mut()
            .zip(z)
            .for_each(|(o, &v)| *o = self.root_lambda * v);
    }

    fn adjoint(&self, r: &[f32], z: &mut [f32]) {
        let (head, tail) = r.split_at(self.k.range_len());
        self.k.adjoint(head, z);
        z.iter_mut()
            .zip(tail)
            .for_each(|(o, &v)| *o += self.root_lambda * v);
    }
}

/// ‖K‖²_F / n, K's mean squared column norm, from one probe: E‖K v‖² =
/// ‖K‖²_F for v of independent ±1 entries.
fn mean_column_norm_sq(k: &dyn LinearOperator) -> f64 {
    let mut rng = crate::rng::Rng::new(0x5ce9e);
    let v: Vec<f32> = (0..k.domain_len())
        .map(|_| if rng.uniform() < 0.5 { -1.0 } else { 1.0 })
        .collect();
    let mut out = vec![0.0f32; k.range_len()];
    k.apply(&v, &mut out);
    out.iter().map(|&x| x as f64 * x as f64).sum::<f64>() / k.domain_len().max(1) as f64
}

/// The fixed parts of the scene fit for one measurement.
pub(crate) struct SceneFit<'a> {
    problem: &'a CalibrationProblem<'a>,
    basis: CoarseScene,
    /// G of H = I − G, on the measurement's frame.
    smooth: GaussianBlur,
    /// H y.
    data: Vec<f32>,
    data_energy: f64,
    settings: SceneFitSettings,
    /// The ridge weight relative to K's mean squared column norm (0: none).
    ridge: f64,
    /// λ, fixed at the first solve.
    lambda: std::sync::OnceLock<f64>,
    /// z₀ of the ridge λ‖z − z₀‖² (`None`: zero).
    anchor: Option<Vec<f32>>,
    /// √w of a weighted fit (`residual_weights.rs`): the residual and K
    /// are multiplied by it after the high-pass (`None`: unweighted).
    root_weights: Option<Vec<f32>>,
}

/// A candidate ψ with its solved coarse scene.
#[derive(Debug, Clone)]
pub(crate) struct Solved {
    pub psi: Mismatch,
    /// The coarse scene's coefficients.
    pub z: Vec<f32>,
    /// r = H y − K_ψ z.
    pub residual: Vec<f32>,
    /// ‖r‖² / ‖H y‖².
    pub score: f64,
}

impl<'a> SceneFit<'a> {
    pub(crate) fn new(
        problem: &'a CalibrationProblem<'a>,
        settings: SceneFitSettings,
    ) -> Result<Self> {
        let (rows, cols) = problem.measurement.shape();
        let (mr, mc) = problem.nominal_mask().shape();
        let basis = CoarseScene::new(
            problem.bands(),
            mr,
            mc,
            settings.cell_px,
            settings.spectral_nodes,
        );
        let smooth = GaussianBlur::new(settings.high_pass_px, rows, cols)?;
        let mut fit = Self {
            problem,
            basis,
            smooth,
            data: vec![0.0; rows * cols],
            data_energy: 0.0,
            settings,
            ridge: 0.0,
            lambda: std::sync::OnceLock::new(),
            anchor: None,
            root_weights: None,
        };
        let mut data = vec![0.0; rows * cols];
        fit.high_pass(problem.measurement.as_slice(), &mut data, &mut Vec::new());
        fit.data_energy = data.iter().map(|&v| v as f64 * v as f64).sum();
        fit.data = data;
        Ok(fit)
    }

    /// The fit with the ridge penalty λ‖z − z₀‖² in its score, λ = `ridge`
    /// × the mean squared column norm of K at the first ψ solved, z₀ =
    /// `anchor` (`None`: zero).
    pub(crate) fn with_ridge(mut self, ridge: f64, anchor: Option<Vec<f32>>) -> Self {
        self.ridge = ridge;
        self.anchor = anchor;
        self
    }

    fn cols(&self) -> usize {
        self.problem.measurement.cols()
    }

    /// The fit with its residual weighted by `weighting`'s weights from
    /// `first`'s residual (a solve of this fit, unweighted).
    pub(crate) fn with_weights(
        self,
        weighting: &ResidualWeighting,
        first: &Solved,
    ) -> Result<Self> {
        let (rows, cols) = self.problem.measurement.shape();
        let root_weights = weighting.root_weights(&first.residual, rows, cols)?;
        Ok(self.with_root_weights(root_weights))
    }

    /// The fit scored on the measurement's rows `first..end` alone (weight
    /// 1 there, 0 elsewhere): the rows around them stay in the model, so
    /// light that crosses the window's edge is still predicted.
    pub(crate) fn with_row_window(self, first: usize, end: usize) -> Self {
        let (rows, cols) = self.problem.measurement.shape();
        let root_weights = (0..rows * cols)
            .map(|i| f32::from((first..end).contains(&(i / cols))))
            .collect();
        self.with_root_weights(root_weights)
    }

    /// √w set, and the data √w ⊙ H y made afresh (any earlier weighting
    /// replaced).
    fn with_root_weights(mut self, root_weights: Vec<f32>) -> Self {
        self.root_weights = Some(root_weights);
        let mut data = std::mem::take(&mut self.data);
        self.high_pass(
            self.problem.measurement.as_slice(),
            &mut data,
            &mut Vec::new(),
        );
        self.weigh(&mut data);
        self.data_energy = data.iter().map(|&v| v as f64 * v as f64).sum();
        self.data = data;
        self
    }

    /// v ← √w ⊙ v (nothing when unweighted).
    fn weigh(&self, v: &mut [f32]) {
        if let Some(w) = &self.root_weights {
            v.iter_mut().zip(w).for_each(|(v, &w)| *v *= w);
        }
    }

    /// The fit with its scene's bands multiplied by `detail` (mask rows ×
    /// cols): the detail pass's.
    pub(crate) fn with_detail(mut self, detail: Vec<f32>) -> Self {
        self.basis = self.basis.with_detail(detail);
        self
    }

    /// The fit with its scene's spectra spanned by `spectra`'s m columns
    /// (bands × m) in place of evenly spaced nodes.
    pub(crate) fn with_spectra(mut self, spectra: &[f64], m: usize) -> Self {
        self.basis = self.basis.with_spectra(spectra, m);
        self
    }

    /// out ← (I − G) frame.
    fn high_pass(&self, frame: &[f32], out: &mut [f32], tmp: &mut Vec<f32>) {
        tmp.resize(frame.len(), 0.0);
        self.smooth.apply(frame, out, tmp);
        out.iter_mut().zip(frame).for_each(|(o, &f)| *o = f - *o);
    }

    /// K at `psi` (the problem's band offsets held), band k moved a further
    /// `along[k]` px along the dispersion where `along` is given
    /// ([`ModelOperator::with_band_shifts`]).
    fn operator(&self, psi: &Mismatch, along: Option<&[f64]>) -> Result<SceneOperator<'_>> {
        self.problem.check_cancelled()?;
        let p = self.problem;
        let op = match along {
            None => p.operator(psi)?,
            // the shifts measured on top of any offsets held
            Some(along) => p.operator_shifted(psi, along)?,
        };
        Ok(SceneOperator { fit: self, op })
    }

    /// ψ with its coarse scene solved, from `warm`'s z (or from zero).
    pub(crate) fn solve(&self, psi: &Mismatch, warm: Option<&[f32]>) -> Result<Solved> {
        match warm {
            Some(z) => self.solve_with(psi, None, Some(z), self.settings.warm_solve),
            None => self.solve_with(psi, None, None, self.settings.cold_solve),
        }
    }

    /// ψ with its coarse scene solved as a first solve (`cold_solve`) from
    /// `from` (or zero).
    pub(crate) fn solve_cold(&self, psi: &Mismatch, from: Option<&[f32]>) -> Result<Solved> {
        self.solve_with(psi, None, from, self.settings.cold_solve)
    }

    /// ‖H y‖² (weighted where the fit is): the score's denominator.
    pub(crate) fn data_energy(&self) -> f64 {
        self.data_energy
    }

    /// ψ with its coarse scene solved by `params` from `from` (or zero).
    fn solve_with(
        &self,
        psi: &Mismatch,
        along: Option<&[f64]>,
        from: Option<&[f32]>,
        params: CglsParams,
    ) -> Result<Solved> {
        let k = self.operator(psi, along)?;
        let mut z = match from {
            Some(z) => z.to_vec(),
            None => vec![0.0; k.domain_len()],
        };
        let mut scratch = CglsScratch::default();
        let n = self.data.len();
        let residual_sq = if self.ridge > 0.0 {
            let lambda = *self
                .lambda
                .get_or_init(|| self.ridge * mean_column_norm_sq(&k));
            let stacked = WithRidge {
                k: &k,
                root_lambda: lambda.sqrt() as f32,
            };
            let mut b = self.data.clone();
            b.resize(n + k.domain_len(), 0.0);
            match &self.anchor {
                None => cgls(&stacked, &b, &mut z, &params, &mut scratch, &mut Silent).residual_sq,
                Some(z0) => {
                    // in w = z − z₀: min ‖(H y − K z₀) − K w‖² + λ‖w‖²
                    let mut kz0 = vec![0.0f32; n];
                    k.apply(z0, &mut kz0);
                    b[..n].iter_mut().zip(&kz0).for_each(|(b, &v)| *b -= v);
                    let mut w: Vec<f32> = z.iter().zip(z0).map(|(z, a)| z - a).collect();
                    let out = cgls(&stacked, &b, &mut w, &params, &mut scratch, &mut Silent);
                    z.iter_mut()
                        .zip(w.iter().zip(z0))
                        .for_each(|(z, (w, a))| *z = w + a);
                    out.residual_sq
                }
            }
        } else {
            cgls(&k, &self.data, &mut z, &params, &mut scratch, &mut Silent).residual_sq
        };
        Ok(Solved {
            psi: *psi,
            z,
            // the data part: the penalty's rows have no ψ in them
            residual: scratch.residual()[..n].to_vec(),
            score: residual_sq / self.data_energy.max(f64::MIN_POSITIVE),
        })
    }

    /// Columns ∂r/∂p at `at` for each of `free` (z held, forward
    /// differences), with the brightness direction K z projected out —
    /// which leaves Jᵀr alone only where r ⊥ K z, so not with a ridge (there
    /// Kᵀr = λz, and the brightness is penalised, not free).
    pub(crate) fn jacobian(&self, at: &Solved, free: &[Parameter]) -> Result<Vec<Vec<f32>>> {
        self.difference_columns(at, free.len(), |i| {
            let (p, h) = (free[i], difference_step(free[i]));
            let mut moved = at.psi;
            p.set(&mut moved, p.get(&at.psi) + h);
            moved.blur_sigma_px = moved.blur_sigma_px.abs();
            Ok((self.operator(&moved, None)?, h))
        })
    }

    /// Columns ∂r/∂δₖ for every band k at `at`, solved at
    /// [`shifted_instrument`]`(base, along)` (z held, forward differences
    /// of [`BAND_SHIFT_STEP`]), as [`Self::jacobian`].
    pub(crate) fn band_shift_jacobian(
        &self,
        at: &Solved,
        base: &Mismatch,
        along: &[f64],
    ) -> Result<Vec<Vec<f32>>> {
        self.difference_columns(at, along.len(), |k| {
            let mut moved = along.to_vec();
            moved[k] += BAND_SHIFT_STEP;
            let (psi, relative) = shifted_instrument(base, &moved);
            Ok((self.operator(&psi, Some(&relative))?, BAND_SHIFT_STEP))
        })
    }

    /// The coarse scene solved at [`shifted_instrument`]`(base, along)` by
    /// `params` (the settings' `cold_solve` or `warm_solve`) from `from`'s
    /// z (or from zero).
    pub(crate) fn solve_band_shifted(
        &self,
        (base, along): (&Mismatch, &[f64]),
        from: Option<&[f32]>,
        params: CglsParams,
    ) -> Result<Solved> {
        let (psi, relative) = shifted_instrument(base, along);
        self.solve_with(&psi, Some(&relative), from, params)
    }

    /// `count` columns −(K′ z − K z) / h, K′ and h from `moved` per column,
    /// the brightness direction K z projected out where no ridge holds it.
    fn difference_columns<'s>(
        &'s self,
        at: &Solved,
        count: usize,
        moved: impl Fn(usize) -> Result<(SceneOperator<'s>, f64)>,
    ) -> Result<Vec<Vec<f32>>> {
        let n = self.data.len();
        let mut images = Vec::new();
        self.basis.band_images(&at.z, &mut images);
        // K z = H y − r
        let kz: Vec<f32> = self
            .data
            .iter()
            .zip(&at.residual)
            .map(|(&d, &r)| d - r)
            .collect();
        let kz_energy: f64 = kz.iter().map(|&v| v as f64 * v as f64).sum();
        let mut columns = Vec::with_capacity(count);
        for i in 0..count {
            let (km, h) = moved(i)?;
            let mut col = vec![0.0f32; n];
            crate::scratch::with_taken(&OPERATOR_SCRATCH, |s| {
                km.frame_of_images(&images, &mut col, s)
            });
            // ∂r/∂p = −(K′ z − K z) / h
            let inv = 1.0 / h as f32;
            col.iter_mut()
                .zip(&kz)
                .for_each(|(c, &base)| *c = (base - *c) * inv);
            if kz_energy > 0.0 && self.ridge == 0.0 {
                let along: f64 = col
                    .iter()
                    .zip(&kz)
                    .map(|(&c, &b)| c as f64 * b as f64)
                    .sum::<f64>()
                    / kz_energy;
                col.iter_mut()
                    .zip(&kz)
                    .for_each(|(c, &b)| *c -= (along * b as f64) as f32);
            }
            columns.push(col);
        }
        Ok(columns)
    }

    /// `z`, the coefficients of `coarser`'s scene, in this fit's basis:
    /// exact where this basis' cells divide the coarser one's.
    pub(crate) fn coefficients_from(&self, coarser: &SceneFit<'_>, z: &[f32]) -> Vec<f32> {
        let mut cube = vec![0.0f32; coarser.basis.range_len()];
        coarser.basis.apply(z, &mut cube);
        self.basis.nodes_of(&cube)
    }

    pub(crate) fn model(&self) -> crate::optics::DispersionModel {
        self.problem.model()
    }

    pub(crate) fn settings(&self) -> &SceneFitSettings {
        &self.settings
    }

    pub(crate) fn frame_shape(&self) -> (usize, usize) {
        self.problem.measurement.shape()
    }

    pub(crate) fn problem(&self) -> &CalibrationProblem<'_> {
        self.problem
    }
}

/// The scene fit's score at `psi` with the coarse scene solved from zero
/// by `settings.cold_solve` (for scans of the objective, e.g. along one
/// parameter; a fit warm-starts instead).
pub fn scene_fit_score(
    problem: &CalibrationProblem<'_>,
    settings: &SceneFitSettings,
    psi: &Mismatch,
) -> Result<f64> {
    problem.validate()?;
    Ok(SceneFit::new(problem, *settings)?.solve(psi, None)?.score)
}

/// The scene fit's scores at each of `psis`, its residual weighted
/// (`residual_weights.rs`) from the cold solve at `weights_at`, every
/// solve cold (for scans of the weighted objective).
pub fn reweighted_scene_fit_scores(
    problem: &CalibrationProblem<'_>,
    settings: &SceneFitSettings,
    weighting: &ResidualWeighting,
    weights_at: &Mismatch,
    psis: &[Mismatch],
) -> Result<Vec<f64>> {
    problem.validate()?;
    let fit = SceneFit::new(problem, *settings)?;
    let first = fit.solve(weights_at, None)?;
    let fit = fit.with_weights(weighting, &first)?;
    psis.iter()
        .map(|psi| Ok(fit.solve(psi, None)?.score))
        .collect()
}

/// `scene` as the scene fit's coarse basis holds it: its values at the
/// basis' nodes, interpolated as the basis interpolates (for measuring
/// what the basis leaves out: a measurement of this cube has no detail
/// the fit cannot explain).
pub fn coarse_scene_of(scene: &Cube, settings: &SceneFitSettings) -> Cube {
    let (bands, rows, cols) = scene.shape();
    let basis = CoarseScene::new(bands, rows, cols, settings.cell_px, settings.spectral_nodes);
    let mut out = Cube::zeros(bands, rows, cols);
    basis.apply(&basis.nodes_of(scene.as_slice()), out.as_mut_slice());
    out
}

/// What the fit found.
pub(crate) struct SceneFitResult {
    pub best: Solved,
    /// Jacobian columns at `best`, one per free parameter.
    pub jacobian: Vec<Vec<f32>>,
    /// Solves and Jacobian columns spent.
    pub evaluations: usize,
}

/// Minimises the score over `free` from `start` by BFGS with a
/// backtracking line search (`quasi_newton.rs`). The gradient is exact at each solved z (Jᵀr,
/// J with z held); the curvature starts from JᵀJ and learns the rest from
/// the gradients' change — JᵀJ alone (Gauss–Newton with z held) overstates
/// it along the directions a re-solved z partly absorbs (dx with a1, α, σ),
/// and took 20 steps of 0.01 px where the minimum lay 0.3 px away.
pub(crate) fn fit_scene(
    fit: &SceneFit<'_>,
    start: &Mismatch,
    free: &[Parameter],
) -> Result<SceneFitResult> {
    fit_scene_from(fit, start, None, free)
}

/// [`fit_scene`] with the first solve run by `cold_solve` from `scene`
/// (another fit's scene in this fit's basis) instead of from zero.
pub(crate) fn fit_scene_from(
    fit: &SceneFit<'_>,
    start: &Mismatch,
    scene: Option<&[f32]>,
    free: &[Parameter],
) -> Result<SceneFitResult> {
    fit_scene_within(fit, start, scene, free, fit.settings().max_steps)
}

/// [`fit_scene_from`] in at most `max_steps` BFGS steps (a probe's short
/// refit on a pass's own objective).
pub(crate) fn fit_scene_within(
    fit: &SceneFit<'_>,
    start: &Mismatch,
    scene: Option<&[f32]>,
    free: &[Parameter],
    max_steps: usize,
) -> Result<SceneFitResult> {
    let first = fit.solve_cold(start, scene)?;
    let found = minimise(&OverParameters { fit, free }, first, max_steps)?;
    Ok(SceneFitResult {
        best: found.best,
        jacobian: found.jacobian,
        evaluations: 1 + found.evaluations,
    })
}

/// The scene fit's score over the `free` parameters of ψ.
struct OverParameters<'a, 'f> {
    fit: &'a SceneFit<'f>,
    free: &'a [Parameter],
}

impl LeastSquares for OverParameters<'_, '_> {
    type Point = Solved;
    fn coordinates(&self, at: &Solved) -> Vec<f64> {
        self.free.iter().map(|&p| p.get(&at.psi)).collect()
    }
    fn residual<'p>(&self, at: &'p Solved) -> &'p [f32] {
        &at.residual
    }
    fn score(&self, at: &Solved) -> f64 {
        at.score
    }
    fn energy(&self) -> f64 {
        self.fit.data_energy
    }
    fn step(&self, at: &Solved, step: &[f64]) -> Result<Solved> {
        let mut psi = at.psi;
        for (&p, &d) in self.free.iter().zip(step) {
            let v = p.get(&psi) + d;
            p.set(&mut psi, v);
        }
        psi.blur_sigma_px = psi.blur_sigma_px.abs();
        self.fit.solve(&psi, Some(&at.z))
    }
    fn jacobian(&self, at: &Solved) -> Result<Vec<Vec<f32>>> {
        self.fit.jacobian(at, self.free)
    }
    fn settled(&self, step: &[f64]) -> bool {
        self.free
            .iter()
            .zip(step)
            .all(|(&p, &d)| d.abs() < settled_step(p))
    }
    /// σ ≥ 0: at (within a settled step of) σ = 0 a sharper model does not
    /// exist. Why: on the captured-mask benchmark instrument the texture fit
    /// often hands the scene fit σ = 0, where every step that lowered σ
    /// came back as |σ| > 0, scored worse, and the first pass stopped at its
    /// start (23 of 240 cases; none on the standard instrument).
    fn on_lower_bound(&self, at: &Solved, i: usize) -> bool {
        self.free[i] == Parameter::BlurSigmaPx
            && at.psi.blur_sigma_px < settled_step(Parameter::BlurSigmaPx)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::quasi_newton::normal_equations;
    use super::*;
    use crate::linop::adjoint_mismatch;
    use crate::optics::{DispersionModel, NoiseModel, PhysicalSpec, simulate_physical};
    use crate::synth::{SceneSpec, random_binary_mask, synthetic_scene};

    /// A 128×128, 16-band physical-simulator measurement (4× oversampled,
    /// crisp mask, blur, noise) of `truth`. (At 64×64 with 8 bands the
    /// spacing pins a1 only to ~0.01 px/band.)
    pub(crate) const BANDS: usize = 16;
    const SIZE: usize = 128;

    pub(crate) fn measured(truth: &Mismatch, noise: bool) -> (crate::Measurement, crate::Mask) {
        measured_scene(truth, noise, 5)
    }

    /// [`measured`] of the synthetic scene drawn from `scene_seed` (the
    /// noise's seed follows it).
    pub(crate) fn measured_scene(
        truth: &Mismatch,
        noise: bool,
        scene_seed: u64,
    ) -> (crate::Measurement, crate::Mask) {
        measured_stepped(truth, noise, scene_seed, None)
    }

    /// [`measured_scene`] of a prism whose bands from `step`'s on land
    /// `step`'s px further along the dispersion.
    pub(crate) fn measured_stepped(
        truth: &Mismatch,
        noise: bool,
        scene_seed: u64,
        step: Option<crate::optics::DispersionStep>,
    ) -> (crate::Measurement, crate::Mask) {
        let spec = PhysicalSpec {
            dispersion_step: step,
            ..PhysicalSpec::default()
        };
        measured_physical(truth, noise, scene_seed, spec)
    }

    /// [`measured_scene`] of the physical instrument `spec` (its blur σ₀
    /// the truth's, its oversampling 4×).
    pub(crate) fn measured_physical(
        truth: &Mismatch,
        noise: bool,
        scene_seed: u64,
        spec: PhysicalSpec,
    ) -> (crate::Measurement, crate::Mask) {
        let (rows, cols, bands) = (SIZE, SIZE, BANDS);
        let wl: Vec<f64> = (0..bands)
            .map(|k| 450.0 + 200.0 / bands as f64 * k as f64)
            .collect();
        let scene = synthetic_scene(&SceneSpec {
            rows,
            cols,
            wavelengths_nm: wl.clone(),
            seed: scene_seed,
        })
        .unwrap();
        let mask = random_binary_mask(rows, cols, 0.5, 11).unwrap();
        let spec = PhysicalSpec {
            oversample: 4,
            blur_sigma_px: truth.blur_sigma_px,
            ..spec
        };
        let noise = noise.then_some(NoiseModel {
            photon_peak: Some(2e4),
            read_noise: 3.0,
            seed: scene_seed.wrapping_sub(3),
        });
        let y = simulate_physical(&scene, &mask, &wl, truth, &spec, noise.as_ref()).unwrap();
        (y, mask)
    }

    pub(crate) fn truth() -> Mismatch {
        Mismatch {
            dx: 0.6,
            dy: -0.4,
            theta_deg: 0.2,
            a1: 2.03,
            alpha_deg: 0.3,
            blur_sigma_px: 0.5,
            a2: 0.0,
        }
    }

    /// K_ψ = H C A_ψ U has an exact adjoint, for a detector narrower and
    /// one wider than the model's (crop and zero pad).
    #[test]
    fn the_scene_operator_has_an_exact_adjoint() {
        let (y, mask) = measured(&truth(), false);
        let problem =
            CalibrationProblem::nominal(&y, &mask, BANDS, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let fit = SceneFit::new(&problem, SceneFitSettings::default()).unwrap();
        for (a1, wider) in [(1.7, false), (2.4, true)] {
            let psi = Mismatch { a1, ..truth() };
            let k = fit.operator(&psi, None).unwrap();
            assert_eq!(k.op.measurement_shape().1 > y.cols(), wider);
            let e = adjoint_mismatch(&k, 3);
            assert!(e < 1e-5, "a1 {a1}: {e}");
        }
        // weighted (√w after H, before it in the adjoint): weights that
        // vary over the frame
        let first = fit.solve(&Mismatch { a1: 1.9, ..truth() }, None).unwrap();
        let fit = fit
            .with_weights(&ResidualWeighting::default(), &first)
            .unwrap();
        let w = fit.root_weights.as_ref().unwrap();
        let (lo, hi) = w
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &v| (a.min(v), b.max(v)));
        assert!(hi > 1.5 * lo, "weights {lo}..{hi}");
        for a1 in [1.7, 2.4] {
            let k = fit.operator(&Mismatch { a1, ..truth() }, None).unwrap();
            let e = adjoint_mismatch(&k, 3);
            assert!(e < 1e-5, "weighted, a1 {a1}: {e}");
        }
    }

    /// The band-shift solves' operators hold the problem's band spread:
    /// with no shift they are the problem's own operator, spread or not.
    #[test]
    fn band_shifted_scene_operators_hold_the_band_spread() {
        use crate::optics::BandSpread;
        let (y, mask) = measured(&truth(), false);
        let plain =
            CalibrationProblem::nominal(&y, &mask, BANDS, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let none = vec![0.0; BANDS];
        let x = crate::synth::synthetic_scene(&crate::synth::SceneSpec {
            rows: mask.rows(),
            cols: mask.cols(),
            wavelengths_nm: (0..BANDS).map(|k| 450.0 + 12.0 * k as f64).collect(),
            seed: 3,
        })
        .unwrap();
        let mut outputs = Vec::new();
        for spread in [BandSpread::Point, BandSpread::Uniform] {
            let problem = plain.with_band_spread(spread);
            let fit = SceneFit::new(&problem, SceneFitSettings::default()).unwrap();
            let shifted = fit
                .operator(&truth(), Some(&none))
                .unwrap()
                .op
                .forward(&x)
                .unwrap();
            let own = problem.operator(&truth()).unwrap().forward(&x).unwrap();
            assert_eq!(shifted.as_slice(), own.as_slice(), "{spread:?}");
            outputs.push(own);
        }
        assert_ne!(outputs[0].as_slice(), outputs[1].as_slice());
    }

    /// The first pass's ridge (a probe) is off by default and absent from
    /// the default's settings; set, it round-trips; a weight that is not
    /// positive and finite is named.
    #[test]
    fn the_first_pass_ridge_is_off_by_default_and_round_trips() {
        let default = SceneFitSettings::default();
        assert_eq!(default.first_pass_ridge, None);
        let json = serde_json::to_string(&default).unwrap();
        assert!(!json.contains("first_pass_ridge"), "{json}");
        let with = SceneFitSettings {
            first_pass_ridge: Some(0.01),
            ..default
        };
        assert!(with.check_first_pass_ridge().is_ok());
        for bad in [0.0, -0.01, f64::NAN, f64::INFINITY] {
            let e = SceneFitSettings {
                first_pass_ridge: Some(bad),
                ..default
            }
            .check_first_pass_ridge()
            .unwrap_err()
            .to_string();
            assert!(e.contains("first_pass_ridge"), "{e}");
        }
        let json = serde_json::to_string(&with).unwrap();
        assert!(json.contains("\"first_pass_ridge\":0.01"), "{json}");
        assert_eq!(
            serde_json::from_str::<SceneFitSettings>(&json).unwrap(),
            with
        );
    }

    /// Settings written before the fine pass read back without one; with
    /// one (the default) they round-trip, its anchor and free set by name.
    #[test]
    fn settings_round_trip_with_and_without_the_fine_pass() {
        assert_eq!(
            SceneFitSettings::default().fine_pass,
            Some(FinePass::default())
        );
        // (the detail pass off: its own `free` is another test's)
        let plain = SceneFitSettings {
            fine_pass: None,
            detail_pass: None,
            ..SceneFitSettings::default()
        };
        let json = serde_json::to_string(&plain).unwrap();
        assert!(!json.contains("fine_pass"), "{json}");
        assert_eq!(
            serde_json::from_str::<SceneFitSettings>(&json).unwrap(),
            plain
        );
        let pairs = RidgeAnchor::ALL
            .into_iter()
            .flat_map(|a| FinePassFree::ALL.map(|f| (a, f)));
        for (anchor, free) in pairs {
            // (without an off-grid run: written before `free` existed, as
            // the check below needs; the run's own free set is another test's)
            let with = SceneFitSettings {
                fine_pass: Some(FinePass {
                    anchor,
                    free,
                    off_grid_run: None,
                    ..FinePass::default()
                }),
                ..plain
            };
            let json = serde_json::to_string(&with).unwrap();
            assert!(json.contains(&format!("\"{}\"", anchor.key())), "{json}");
            assert!(json.contains(&format!("\"{}\"", free.key())), "{json}");
            assert_eq!(
                serde_json::from_str::<SceneFitSettings>(&json).unwrap(),
                with
            );
            assert_eq!(anchor.key().parse::<RidgeAnchor>().unwrap(), anchor);
            assert_eq!(free.key().parse::<FinePassFree>().unwrap(), free);
            // written before `free` existed: the pose and slope, as they ran
            let old = json.replace(&format!(",\"free\":\"{}\"", free.key()), "");
            assert!(!old.contains("\"free\""), "{old}");
            let read = serde_json::from_str::<SceneFitSettings>(&old).unwrap();
            assert_eq!(read.fine_pass.unwrap().free, FinePassFree::PoseAndSlope);
        }
        assert!("nope".parse::<RidgeAnchor>().is_err());
        assert!("nope".parse::<FinePassFree>().is_err());
        // the two probes' options: absent by default (the records before
        // them read back unchanged), written and read back when on
        let default_json = serde_json::to_string(&FinePass::default()).unwrap();
        assert!(!default_json.contains("carries_detail"), "{default_json}");
        assert!(!default_json.contains("weighting"), "{default_json}");
        assert!(!default_json.contains("high_pass_px"), "{default_json}");
        assert!(!default_json.contains("spectral_basis"), "{default_json}");
        let probe = FinePass {
            carries_detail: true,
            weighting: Some(ResidualWeighting::default()),
            high_pass_px: Some(4.0),
            spectral_basis: Some(SpectralBasis {
                components: 6,
                gap_iterations: 50,
            }),
            on_grid: Some(OnGridNodes {
                from_first_answer: true,
                ..OnGridNodes::default()
            }),
            ..FinePass::default()
        };
        let json = serde_json::to_string(&probe).unwrap();
        assert!(json.contains("\"carries_detail\":true"), "{json}");
        assert!(json.contains("\"from_first_answer\":true"), "{json}");
        assert_eq!(serde_json::from_str::<FinePass>(&json).unwrap(), probe);
        // the on-grid nodes: written by default, absent from (so off in)
        // settings written before them
        assert!(default_json.contains("\"on_grid\""), "{default_json}");
        assert_eq!(
            serde_json::from_str::<FinePass>(&default_json).unwrap(),
            FinePass::default()
        );
        let before: serde_json::Value = serde_json::from_str(&default_json).unwrap();
        let mut before = before.as_object().unwrap().clone();
        before.remove("on_grid");
        let read: FinePass = serde_json::from_value(before.into()).unwrap();
        assert_eq!(read.on_grid, None);
        // on-grid settings written before `from_first_answer` and
        // `judged_at_start_below`: from the start, judged at the answer
        let old_on_grid: OnGridNodes =
            serde_json::from_str(r#"{"spectral_nodes":10,"below_phase":0.5}"#).unwrap();
        assert_eq!(
            old_on_grid,
            OnGridNodes {
                judged_at_start_below: None,
                ..OnGridNodes::default()
            }
        );
    }

    /// `f` given a fine pass's start: the scene fit's tests' measurement, the
    /// default settings, the first pass's fit and its solve at the truth.
    fn from_a_first_pass<R>(
        f: impl FnOnce(&CalibrationProblem<'_>, SceneFitSettings, &SceneFit<'_>, &Solved) -> R,
    ) -> R {
        let truth = truth();
        let (y, mask) = measured(&truth, false);
        let problem =
            CalibrationProblem::nominal(&y, &mask, BANDS, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let settings = SceneFitSettings::default();
        let coarse = SceneFit::new(&problem, settings.first_pass_only()).unwrap();
        let first = coarse.solve(&truth, None).unwrap();
        f(&problem, settings, &coarse, &first)
    }

    /// With principal spectra the fine pass's scene lives on them: as many
    /// coefficients per node as spectra (3 here against the default's 6
    /// nodes), its start the first pass's scene projected onto them.
    #[test]
    fn the_fine_pass_on_principal_spectra_solves_its_scene_on_them() {
        from_a_first_pass(|problem, settings, coarse, first| {
            let per_spectrum = |spectral_basis: Option<SpectralBasis>, m: usize| {
                let pass = FinePass {
                    spectral_basis,
                    ..FinePass::default()
                };
                let (fine, scene) = pass
                    .scene_fit(problem, settings, (coarse, first), None)
                    .unwrap();
                assert_eq!(scene.len(), fine.basis.domain_len());
                assert_eq!(scene.len() % m, 0);
                scene.len() / m
            };
            let basis = SpectralBasis {
                components: 3,
                gap_iterations: 10,
            };
            assert_eq!(
                per_spectrum(Some(basis), 3),
                per_spectrum(None, settings.spectral_nodes)
            );
        });
    }

    /// The fine pass takes its on-grid nodes below their phase only, and
    /// never over nodes set outright (a probe's) or with the option off;
    /// from a start below its bound it takes them without the judging run.
    #[test]
    fn the_fine_pass_takes_more_spectral_nodes_on_the_pixel_grid_only() {
        let pass = FinePass::default();
        let on_grid = pass.on_grid.unwrap();
        let near = pass.again_at(0.2).expect("run again on the grid");
        assert_eq!(near.spectral_nodes, Some(on_grid.spectral_nodes));
        assert_eq!(
            FinePass {
                spectral_nodes: None,
                off_grid_run: pass.off_grid_run,
                ..near
            },
            pass
        );
        for phase in [on_grid.below_phase, 1.0, 1.5, f64::NAN] {
            assert_eq!(pass.again_at(phase), None, "phase {phase}");
        }
        let probe = FinePass {
            spectral_nodes: Some(8),
            ..pass
        };
        assert_eq!(probe.again_at(0.0), None);
        // its own nodes off the grid give way to the on-grid run's on it
        let off_grid = FinePass {
            off_grid_nodes: Some(6),
            ..pass
        };
        assert_eq!(pass.nodes_after(4), 4);
        assert_eq!(off_grid.nodes_after(4), 6);
        let again = off_grid.again_at(0.2).expect("run again on the grid");
        assert_eq!(again.nodes_after(4), on_grid.spectral_nodes);
        assert_eq!(probe.nodes_after(4), 8);
        let off = FinePass {
            on_grid: None,
            ..pass
        };
        assert_eq!(off.again_at(0.0), None);
        // a start already on the grid goes straight to the on-grid run (the
        // same pass `again_at` gives), judged at the start below its bound
        let below = on_grid.judged_at_start_below.expect("judged at the start");
        assert_eq!(pass.again_from_start(below - 0.01), Some(near));
        for phase in [below, 0.86, f64::NAN] {
            assert_eq!(pass.again_from_start(phase), None, "phase {phase}");
        }
        assert_eq!(probe.again_from_start(0.0), None);
        assert_eq!(off.again_from_start(0.0), None);
        for on_grid in [
            // settings written before the bound: judged at the answer
            OnGridNodes {
                judged_at_start_below: None,
                ..on_grid
            },
            // from the first run's answer: that run is needed
            OnGridNodes {
                from_first_answer: true,
                ..on_grid
            },
        ] {
            let pass = FinePass {
                on_grid: Some(on_grid),
                ..pass
            };
            assert_eq!(pass.again_from_start(0.0), None, "{on_grid:?}");
        }
    }

    /// The default's off-grid run's own warm solves and free set hold in
    /// the pass's first run only: its scene fit solves with them, and the
    /// on-grid run (either way it is reached) keeps the pass's; settings
    /// written before the field read back without it, as they ran.
    #[test]
    fn an_off_grid_runs_solves_and_free_set_stay_off_the_grid() {
        let pass = FinePass::default();
        let run = pass.off_grid_run.expect("on by default");
        assert_eq!(run.warm_solve.iterations, 60);
        assert_eq!(pass.run_free(), FinePassFree::PoseAndSlope);
        assert_eq!(pass.free, FinePassFree::Geometry);
        let without = FinePass {
            off_grid_run: None,
            ..pass
        };
        assert_eq!(without.run_free(), FinePassFree::Geometry);
        // its answer is the run's unless the pass's own refit follows it
        assert_eq!(pass.then(), None);
        assert_eq!(pass.answer_free(), FinePassFree::PoseAndSlope);
        let then = FinePass {
            off_grid_run: Some(OffGridRun {
                then_the_pass: true,
                ..run
            }),
            ..pass
        };
        assert_eq!(then.then(), Some(without));
        assert_eq!(then.answer_free(), FinePassFree::Geometry);
        assert_eq!(then.run_free(), FinePassFree::PoseAndSlope);
        // a refit of what the run held alone, whose fit states the fine block
        let across = FinePass {
            off_grid_run: Some(OffGridRun {
                then_the_pass: true,
                then_free: Some(FinePassFree::DyAndAlpha),
                ..run
            }),
            ..pass
        };
        let across_then = across.then().expect("a refit after the run");
        assert_eq!(across_then.free, FinePassFree::DyAndAlpha);
        assert_eq!(across_then.off_grid_run, None);
        assert_eq!(across.answer_free(), FinePassFree::DyAndAlpha);
        // a free set named without the flag still runs its refit
        let named = FinePass {
            off_grid_run: Some(OffGridRun {
                then_the_pass: false,
                then_free: Some(FinePassFree::DyAndAlpha),
                ..run
            }),
            ..pass
        };
        assert_eq!(named.then(), across.then());
        let json = serde_json::to_string(&across).unwrap();
        assert_eq!(serde_json::from_str::<FinePass>(&json).unwrap(), across);
        for again in [pass.again_at(0.2), pass.again_from_start(0.2)] {
            let again = again.expect("run again on the grid");
            assert_eq!(again.off_grid_run, None);
            assert_eq!(again.run_free(), FinePassFree::Geometry);
        }
        from_a_first_pass(|problem, settings, coarse, first| {
            let warm_of = |pass: &FinePass| {
                let (fine, _) = pass
                    .scene_fit(problem, settings, (coarse, first), None)
                    .unwrap();
                fine.settings.warm_solve
            };
            assert_ne!(run.warm_solve, settings.warm_solve);
            assert_eq!(warm_of(&pass), run.warm_solve);
            assert_eq!(warm_of(&pass.again_at(0.2).unwrap()), settings.warm_solve);
            assert_eq!(warm_of(&without), settings.warm_solve);
        });
        let json = serde_json::to_string(&without).unwrap();
        assert!(!json.contains("off_grid_run"), "{json}");
        assert_eq!(serde_json::from_str::<FinePass>(&json).unwrap(), without);
        let json = serde_json::to_string(&pass).unwrap();
        assert_eq!(serde_json::from_str::<FinePass>(&json).unwrap(), pass);
    }

    /// Settings written before the detail pass read back without one; with
    /// one they round-trip, its free set by name.
    #[test]
    fn settings_round_trip_with_and_without_the_detail_pass() {
        let plain = SceneFitSettings {
            detail_pass: None,
            ..SceneFitSettings::default()
        };
        let json = serde_json::to_string(&plain).unwrap();
        assert!(!json.contains("detail_pass"), "{json}");
        assert_eq!(
            serde_json::from_str::<SceneFitSettings>(&json).unwrap(),
            plain
        );
        for free in FinePassFree::ALL {
            let with = SceneFitSettings {
                detail_pass: Some(DetailPass {
                    free,
                    ..DetailPass::default()
                }),
                ..plain
            };
            let json = serde_json::to_string(&with).unwrap();
            assert!(json.contains("detail_pass"), "{json}");
            assert_eq!(
                serde_json::from_str::<SceneFitSettings>(&json).unwrap(),
                with
            );
        }
    }

    /// A scene that is a texture times a smooth scene is held by the detail
    /// pass's basis with that texture as its detail map: at the true ψ its
    /// solved scene leaves ~nothing, where the plain coarse scene leaves the
    /// texture (the measurement here is the model's own product: a test of
    /// the basis, not of the calibration).
    #[test]
    fn a_textured_scene_is_held_by_the_detail_basis() {
        let (_, mask) = measured(&truth(), false);
        let psi = truth();
        let op = ModelOperator::new(&mask, BANDS, &psi, DispersionModel::DispersedMask).unwrap();
        let (rows, det) = op.measurement_shape();
        let detail: Vec<f32> = (0..SIZE * SIZE)
            .map(|i| {
                let (r, c) = ((i / SIZE) as f32, (i % SIZE) as f32);
                1.0 + 0.6 * (0.9 * r).sin() * (0.7 * c + 0.3 * r).cos()
            })
            .collect();
        let settings = SceneFitSettings {
            cold_solve: CglsParams {
                iterations: 300,
                tolerance: 1e-9,
            },
            ..SceneFitSettings::default()
        };
        // the scene in the fit's own basis
        let smooth = CoarseScene::new(BANDS, SIZE, SIZE, settings.cell_px, settings.spectral_nodes);
        let z0: Vec<f32> = (0..smooth.domain_len())
            .map(|i| 0.5 + ((i * 13) % 7) as f32 / 14.0)
            .collect();
        let mut cube = vec![0.0f32; smooth.range_len()];
        smooth
            .clone()
            .with_detail(detail.clone())
            .apply(&z0, &mut cube);
        let mut y = vec![0.0f32; rows * det];
        op.apply(&cube, &mut y);
        let y = crate::Measurement::from_vec(rows, det, y).unwrap();
        let problem =
            CalibrationProblem::nominal(&y, &mask, BANDS, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let plain = SceneFit::new(&problem, settings).unwrap();
        let detailed = SceneFit::new(&problem, settings)
            .unwrap()
            .with_detail(detail);
        let (plain, detailed) = (
            plain.solve(&psi, None).unwrap().score,
            detailed.solve(&psi, None).unwrap().score,
        );
        assert!(detailed < 1e-4, "detail basis leaves {detailed}");
        assert!(
            plain > 100.0 * detailed,
            "plain {plain}, detailed {detailed}"
        );
    }

    /// K_ψ z made a row at a time equals the model's own operator applied
    /// to the stored coarse cube, high-passed, sharp and blurred.
    #[test]
    fn the_row_by_row_product_is_the_models() {
        let (y, mask) = measured(&truth(), false);
        let problem =
            CalibrationProblem::nominal(&y, &mask, BANDS, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let fit = SceneFit::new(&problem, SceneFitSettings::default()).unwrap();
        let z: Vec<f32> = (0..fit.basis.domain_len())
            .map(|i| ((i * 31) % 17) as f32 / 17.0)
            .collect();
        for sigma in [0.0, 0.6] {
            let psi = Mismatch {
                blur_sigma_px: sigma,
                ..truth()
            };
            let k = fit.operator(&psi, None).unwrap();
            let mut fused = vec![0.0f32; k.range_len()];
            k.apply(&z, &mut fused);
            let mut cube = vec![0.0f32; fit.basis.range_len()];
            fit.basis.apply(&z, &mut cube);
            let (rows, det) = k.op.measurement_shape();
            let mut detector = vec![0.0f32; rows * det];
            k.op.apply(&cube, &mut detector);
            let mut frame = Vec::new();
            reframe(&detector, det, &mut frame, y.cols());
            let mut expected = vec![0.0f32; fit.data.len()];
            fit.high_pass(&frame, &mut expected, &mut Vec::new());
            let scale = expected.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            let worst = fused
                .iter()
                .zip(&expected)
                .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
            assert!(worst <= 1e-5 * scale, "σ {sigma}: {worst} of {scale}");
        }
    }

    /// The gradient the fit steps along, 2 Jᵀr / ‖H y‖² with z held, is the
    /// derivative of the score with z re-solved (the variable-projection
    /// identity), to finite-difference accuracy, for every parameter.
    #[test]
    fn the_held_z_gradient_is_the_scores_derivative() {
        let (y, mask) = measured(&truth(), true);
        let problem =
            CalibrationProblem::nominal(&y, &mask, BANDS, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let converged = CglsParams {
            iterations: 400,
            tolerance: 1e-9,
        };
        // the first pass's scene, and the fine pass's with its ridge toward
        // zero and toward another scene (the ridge's rows hold no ψ: the
        // same identity)
        let ridge = FinePass::default().ridge;
        let cases = [
            (8, 0.0, false, false),
            (8, 0.0, false, true),
            (4, ridge, false, false),
            (4, ridge, true, false),
        ];
        for (cell_px, ridge, anchored, weighted) in cases {
            let settings = SceneFitSettings {
                cell_px,
                cold_solve: converged,
                warm_solve: converged,
                ..SceneFitSettings::default()
            };
            let fit = SceneFit::new(&problem, settings).unwrap();
            let anchor = anchored.then(|| {
                let first = SceneFit::new(&problem, SceneFitSettings::default()).unwrap();
                let z = first.solve(&truth(), None).unwrap().z;
                fit.coefficients_from(&first, &z)
            });
            let mut fit = fit.with_ridge(ridge, anchor);
            if weighted {
                // weights from another ψ's residual, held
                let first = fit.solve(&truth(), None).unwrap();
                fit = fit
                    .with_weights(&ResidualWeighting::default(), &first)
                    .unwrap();
            }
            // every band's landing phase away from whole pixels: the bilinear
            // mask sampling makes the score piecewise smooth, with kinks there
            let at = Mismatch {
                dx: 0.45,
                dy: -0.5,
                blur_sigma_px: 0.7,
                ..truth()
            };
            let solved = fit.solve(&at, None).unwrap();
            let free = Parameter::CALIBRATED;
            let columns = fit.jacobian(&solved, &free).unwrap();
            let (_, jtr) = normal_equations(&columns, &solved.residual);
            for (i, &p) in free.iter().enumerate() {
                let analytic = 2.0 * jtr[i] / fit.data_energy;
                let h = 4.0 * difference_step(p);
                let score = |d: f64| {
                    let mut m = at;
                    p.set(&mut m, p.get(&at) + d);
                    fit.solve(&m, Some(&solved.z)).unwrap().score
                };
                let numeric = (score(h) - score(-h)) / (2.0 * h);
                assert!(
                    (analytic - numeric).abs() <= 0.1 * numeric.abs().max(1e-3 * solved.score / h),
                    "cell {cell_px}, ridge {ridge} (anchored {anchored}, weighted {weighted}), {p:?}: held-z {analytic:.4e}, re-solved {numeric:.4e}"
                );
            }
        }
    }

    /// From a start 0.3 px, 0.3° of tilt, 0.015 px/band and 0.2 px of blur
    /// off, the fit returns the instrument of a physical-simulator
    /// measurement (4× oversampled: no operator it fits made it) to within
    /// a fifth of the start's error in the shifts and a1 and half in the
    /// blur, and its score at the answer is at most the truth's.
    #[test]
    fn the_fit_recovers_a_misaligned_instrument() {
        let t = truth();
        let (y, mask) = measured(&t, true);
        let problem =
            CalibrationProblem::nominal(&y, &mask, BANDS, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let fit = SceneFit::new(&problem, SceneFitSettings::default()).unwrap();
        let start = Mismatch {
            dx: t.dx - 0.3,
            dy: t.dy + 0.3,
            a1: t.a1 + 0.015,
            alpha_deg: t.alpha_deg - 0.3,
            blur_sigma_px: 0.3,
            ..t
        };
        let found = fit_scene(&fit, &start, &Parameter::CALIBRATED).unwrap();
        for (p, tol) in [
            (Parameter::Dx, 0.06),
            (Parameter::Dy, 0.06),
            (Parameter::A1, 0.003),
            (Parameter::BlurSigmaPx, 0.1),
        ] {
            let e = p.get(&found.best.psi) - p.get(&t);
            assert!(
                e.abs() <= tol,
                "{p:?} error {e:+.4} (found {:?})",
                found.best.psi
            );
        }
        let at_truth = fit.solve(&t, Some(&found.best.z)).unwrap().score;
        assert!(found.best.score <= at_truth * (1.0 + 1e-4));
        assert_eq!(found.jacobian.len(), Parameter::CALIBRATED.len());

        // the stated errors carry the disagreement with the texture fit: a
        // texture answer 0.4 px of blur away widens σ's bar to at least
        // 0.4/√2, and one that agrees leaves the sandwich and floor alone
        use super::super::uncertainty::scene_fit_uncertainty;
        let free = Parameter::CALIBRATED;
        let agree = scene_fit_uncertainty(&fit, &found, &free, &found.best.psi);
        let other = Mismatch {
            blur_sigma_px: found.best.psi.blur_sigma_px + 0.4,
            ..found.best.psi
        };
        let apart = scene_fit_uncertainty(&fit, &found, &free, &other);
        let blur = |u: &super::super::uncertainty::UncertaintyEstimate| {
            u.standard.get(Parameter::BlurSigmaPx).unwrap()
        };
        assert!(blur(&apart) >= 0.4 / 2f64.sqrt(), "{}", blur(&apart));
        assert!(blur(&agree) < 0.2, "{}", blur(&agree));
        assert_eq!(
            agree.standard.get(Parameter::Dx),
            apart.standard.get(Parameter::Dx)
        );
    }
}
