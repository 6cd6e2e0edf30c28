//! Self-calibration: recover the mismatch ψ = (dx, dy, θ, a1, α) from one
//! measurement and the nominal mask, with no ground truth, by minimising
//! the residual of a short proxy reconstruction (paper §3.3, Eq. 3).
//!
//! Presets: `default` (ours, [`calibrate_default`]) and `paper` (the paper's
//! Algorithm 1, [`calibrate_paper`]), each a short recipe of stages over
//! the stage runner (`stages.rs`), which reports every stage's evaluations,
//! time and best ψ. The searches (Nelder–Mead, Adam, the grids) minimise an
//! `Objective` (`objective.rs`): a score over a subset of ψ's parameters.

pub(crate) mod adam;
mod band_shifts;
mod blur_bootstrap;
mod blur_pass;
mod coarse_scene;
mod default;
mod detail_pass;
pub(crate) mod gradient;
mod grid;
pub(crate) mod init;
mod joint_fit;
pub(crate) mod nelder_mead;
mod nominal_start;
mod objective;
mod on_pool;
mod paper;
mod quasi_newton;
mod residual_weights;
mod ridge_probes;
mod rounded_dispersion;
mod row_window;
mod scene_fit;
pub(crate) mod score;
pub(crate) mod smooth;
mod snapshots;
mod spectral_basis;
mod stages;
mod subpixel_tilt;
mod texture;
mod uncertainty;

pub use uncertainty::{
    A1_SHORT_TILT_DEG, CURVATURE_FLOOR, CURVATURE_FLOOR_95, Fit, SHARP_BLUR_PX,
    TRADE_OFF_CORRELATION, TradeOff, WIDE_BLUR_PX, grid_phase, interval_95_floor,
    model_error_floor, spread_scale,
};

use serde::{Deserialize, Serialize};

pub use adam::AdamSettings;
pub use band_shifts::{BandShiftFit, BandShifts, band_shift_scores, fit_band_shifts};
pub use blur_bootstrap::BlurBootstrap;
pub use blur_pass::{
    BlurPass, BlurPassStart, ON_GRID_MARGIN_PX, OnGridMargin, ReconstructionSigma,
    TEXTURE_START_MAX_PX,
};
pub use default::{
    BLUR_BOOTSTRAP_STAGE, BLUR_PASS_STAGE, DETAIL_PASS_STAGE, DefaultPreset,
    NOMINAL_A1_RESTART_PREFIX, NOMINAL_A1_RESTART_STAGE, NOMINAL_START_STAGE, RIDGE_PROBES_STAGE,
    SCENE_FIT_STAGE, calibrate_default, texture_fit,
};
pub use detail_pass::{DetailPass, DetailSource};
pub use gradient::Parameter;
pub use joint_fit::{
    JOINT_DETAIL_PASS_STAGE, JOINT_FINE_PASS_STAGE, JointFit, joint_scene_fit, refit_jointly,
};
pub use nelder_mead::nelder_mead;
pub use nominal_start::NominalStart;
pub use paper::{GradientStage, PaperPreset, calibrate_paper};
pub use residual_weights::ResidualWeighting;
pub use ridge_probes::{
    BandEnd, DISTINCT_PX, ProbeEnd, Ridge, RidgeProbeReport, RidgeProbes, RidgeProfile,
};
pub use scene_fit::{
    FinePass, FinePassFree, OffGridRun, OnGridNodes, RidgeAnchor, SceneFitSettings,
    coarse_scene_of, reweighted_scene_fit_scores, scene_fit_score,
};
pub use score::{CalibrationProblem, ProxyParams, gap_tv_reconstruction};
pub use smooth::{gaussian_taps, smooth_bands};
pub use snapshots::{Centre, CombineParams, Consistency, SnapshotSpread, combine_snapshots};
pub use spectral_basis::SpectralBasis;
pub use texture::{SCENE_SMOOTH_PX, SceneEstimate};

use crate::optics::{BandOffsets, BandSpread, DispersionModel};
use crate::params::Mismatch;

/// `dst` ← `src` (rows of `src_cols`) on rows of `dst_cols`: each row's
/// first min(src_cols, dst_cols) values, zeros after — the crop of a
/// model's detector to the measurement's width, or the zero pad back.
pub(crate) fn reframe(src: &[f32], src_cols: usize, dst: &mut Vec<f32>, dst_cols: usize) {
    let rows = src.len() / src_cols.max(1);
    dst.clear();
    dst.resize(rows * dst_cols, 0.0);
    let keep = src_cols.min(dst_cols);
    for (d, s) in dst.chunks_mut(dst_cols).zip(src.chunks(src_cols)) {
        d[..keep].copy_from_slice(&s[..keep]);
    }
}

/// What one stage did.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StageReport {
    pub name: String,
    /// Score evaluations; for a gradient stage, gradient evaluations (each
    /// costs about 1 + 2P scores for P parameters).
    pub evaluations: usize,
    pub seconds: f64,
    pub parameters: Mismatch,
    /// Proxy score at `parameters` with this stage's proxy.
    pub score: f64,
    /// A stage that chose between two answers (the held curvature's
    /// restart from the nominal a1, the scene fit's nominal start): the one
    /// it did not keep, with its score on the same objective (higher). The
    /// held curvature's restart adds the two's difference to the kept
    /// answer's errors (its objective chose wrongly on the tuning half);
    /// the nominal start does not (see [`NominalStart`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passed_over: Option<PassedOver>,
}

/// The answer a choosing stage did not keep ([`StageReport::passed_over`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PassedOver {
    pub parameters: Mismatch,
    /// Its score on the objective that chose (higher than the kept one's).
    pub score: f64,
}

/// The result of a calibration.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Calibration {
    pub preset: String,
    pub model: DispersionModel,
    pub parameters: Mismatch,
    /// Score of `parameters` with the final proxy.
    pub score: f64,
    /// Score of the nominal parameters with the final proxy.
    pub nominal_score: f64,
    /// Standard error per parameter (pixels / degrees / px-per-band). The
    /// `default` preset: the block sandwich of its last fit — the scene fit
    /// for the dispersed-mask model, the texture fit for the subpixel one
    /// (spatially correlated residuals counted per image block, not per
    /// pixel) — with a model-error floor in quadrature, set on the physical
    /// benchmark's tuning half for 68 % coverage and checked on the
    /// held-out half (`bench/results/calibrate_physical_held_out.json`).
    /// The `paper` preset: the proxy score's curvature, treating it as a
    /// mean squared residual of N independent pixels (it is not; it does
    /// not cover). `None` where not estimated.
    pub uncertainty: Uncertainty,
    /// Half-width of the 95 % interval per parameter (the `default` preset's
    /// texture fit; empty otherwise and in records written before it). Not
    /// 2 × `uncertainty`: the errors are heavy-tailed (a rare fit lands up
    /// to a pixel off along the dx–a1 ridge), so it carries its own floor,
    /// set on the tuning half for 95 % coverage.
    #[serde(default, skip_serializing_if = "Uncertainty::is_empty")]
    pub interval_95: Uncertainty,
    /// Pairs of parameters whose estimates are correlated by at least
    /// [`TRADE_OFF_CORRELATION`]: the data pin their combination, not each.
    /// The `default` preset reads them from its whole stated covariance:
    /// the sandwich's plus the floors', correlated as the errors were on the
    /// benchmark's tuning half (dy with α, dx with a1, θ with α).
    #[serde(default)]
    pub trade_offs: Vec<TradeOff>,
    /// The fit the standard errors and 95 % intervals come from (each has
    /// its own floors, set and checked on the benchmark); `None` for the
    /// curvature-based errors and in records written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty_fit: Option<Fit>,
    /// Where the ridge probes ended, when they ran (`default` preset with
    /// [`DefaultPreset::ridge_probes`]; `None` otherwise and in records
    /// made before them): each a dip of the objective's profile along the
    /// dx–a1 or dy–α ridge, refitted (none: no dip); those marked
    /// `alternative` scored within the probes' margin of `parameters`, and
    /// the stated errors reach them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ridge_probes: Option<RidgeProbeReport>,
    /// σ as `model` itself fits it, where the stage that set
    /// `parameters.blur_sigma_px` read it on another model and the
    /// calibration reconstructs with the model's own: the default's blur
    /// pass reads the instrument's blur on the crisp-cell model; from stop
    /// 44 to 62 the dispersed-mask model reconstructed with its own fit's
    /// σ, since stop 63 with the pass's, except where the pass runs as
    /// before stop 62 (the real snapshots; [`ReconstructionSigma`]).
    /// `None`: reconstruct with `parameters` as they are. See
    /// [`Calibration::reconstruction_parameters`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_blur_sigma_px: Option<f64>,
    /// Where the answer lies on the pixel grid: the σ the calibrated model
    /// reconstructs with is raised by this much ([`OnGridMargin`]; the
    /// reported σ stays the instrument's). `None`: no margin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub on_grid_margin_px: Option<f64>,
    /// Set where this calibration combines several snapshots' of one
    /// instrument ([`combine_snapshots`]): their answers and whether they
    /// agree; `stages` are then the snapshots' answers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub snapshots: Option<SnapshotSpread>,
    /// The bands' departures from the straight dispersion the calibration
    /// held ([`CalibrationProblem::with_band_offsets`]): part of the
    /// instrument, so a reconstruction with these parameters holds them
    /// too. `None`: the dispersion a1·k + a2·k² alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band_offsets: Option<BandOffsets>,
    /// Where each band's light lies along the dispersion in the model the
    /// calibration fitted ([`CalibrationProblem::with_band_spread`]): part
    /// of the instrument, so a reconstruction with these parameters spreads
    /// it too. Not written for a point (every model's before it).
    #[serde(default, skip_serializing_if = "BandSpread::is_point")]
    pub band_spread: BandSpread,
    pub stages: Vec<StageReport>,
    pub seconds: f64,
    pub evaluations: usize,
}

impl Calibration {
    /// The parameters `model`'s operator reconstructs with: `parameters`,
    /// σ the model's own fit where it has one ([`Self::model_blur_sigma_px`])
    /// plus the on-grid margin where it applies ([`Self::on_grid_margin_px`]).
    /// What `cassi reconstruct --calibration`, the Python `reconstruct` and
    /// the evaluation's corrected scenario use; `parameters` are the
    /// instrument's, as reported.
    pub fn reconstruction_parameters(&self) -> Mismatch {
        Mismatch {
            blur_sigma_px: self
                .model_blur_sigma_px
                .unwrap_or(self.parameters.blur_sigma_px)
                + self.on_grid_margin_px.unwrap_or(0.0),
            ..self.parameters
        }
    }

    /// `p`'s 95 % interval as (low, high): the estimate ∓ its stated
    /// half-width, the low end raised to the least value the parameter can
    /// take ([`Parameter::lower_bound`]: a blur's 0), so a σ the data do
    /// not resolve from 0 reads (0, high). `None` where no half-width was
    /// stated. The Python `ranges_95`; the line [`Self::uncertainty_line`]
    /// prints.
    pub fn range_95(&self, p: Parameter) -> Option<(f64, f64)> {
        let w = self.interval_95.get(p)?;
        let value = p.get(&self.parameters);
        let low = p
            .lower_bound()
            .map_or(value - w, |least| (value - w).max(least));
        Some((low, value + w))
    }

    /// "dx    -0.567 ± 0.881 px   (95 %: ± 2.012)": `p`'s estimate with its
    /// standard error and, where stated, its 95 % half-width; `None` where
    /// no standard error was estimated. Where that interval reaches below
    /// what the parameter can take (a blur's 0), it is printed as the range
    /// it leaves, "(95 %: 0.000 to 2.269, bounded above only)": a σ the
    /// data do not resolve from 0 (the small-σ reads of stop 73's held-out
    /// pool) says so rather than "± 2.173" about 0.096. What the CLI and the
    /// Python repr print.
    pub fn uncertainty_line(&self, p: Parameter) -> Option<String> {
        let u = self.uncertainty.get(p)?;
        let prec = p.decimals();
        let value = p.get(&self.parameters);
        let interval = match (self.interval_95.get(p), self.range_95(p)) {
            (Some(w), Some((low, high))) if low > value - w => format!(
                "   (95 %: {} to {}, bounded above only)",
                p.format(low),
                p.format(high)
            ),
            (Some(w), _) => format!("   (95 %: ± {w:.prec$})"),
            (None, _) => String::new(),
        };
        Some(format!(
            "{:<5} {} ± {u:.prec$} {}{interval}",
            p.name(),
            p.format(value),
            p.unit(),
        ))
    }
}

/// A standard error per parameter, `None` where it was not estimated;
/// written as `{"dx": …, "dy": …, "theta_deg": …, "a1": …, "alpha_deg": …}`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Uncertainty(pub std::collections::BTreeMap<Parameter, Option<f64>>);

impl Uncertainty {
    /// The standard error of `p`, if it was estimated.
    pub fn get(&self, p: Parameter) -> Option<f64> {
        self.0.get(&p).copied().flatten()
    }

    /// No parameter listed.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// A calibration preset with its settings.
// one per calibration, never held in bulk: boxing the larger variant would
// buy nothing but an indirection in every caller's match
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "preset", rename_all = "lowercase")]
pub enum Preset {
    Default(DefaultPreset),
    Paper(PaperPreset),
}

/// The preset names the CLI accepts.
pub const PRESET_NAMES: [&str; 2] = ["default", "paper"];

impl Preset {
    /// The model a preset calibrates when none is asked for: the
    /// dispersed-mask model (ours, for real instruments) for `default`; the
    /// subpixel model for `paper`, whose gradients differentiate one mask
    /// shared by every band.
    pub fn default_model(&self) -> DispersionModel {
        match self {
            Self::Default(_) => DispersionModel::DispersedMask,
            Self::Paper(_) => DispersionModel::Subpixel,
        }
    }

    /// Where each band's light lies in `model` when the caller asks for
    /// nothing ([`CalibrationProblem::with_band_spread`]): spread evenly
    /// over the band's width (a camera's spectrum is continuous) for the
    /// default preset's blur-aware models, the dispersed-mask and crisp-cell
    /// models, whose blur the spread's row kernel joins (stop 58: held out
    /// on a continuous-spectrum instrument, 43 of 70 against the point
    /// model's 10; the real snapshots' residual lower on 5 of 5); a point
    /// per band for the paper preset (its gradients know no other) and for
    /// the rounded and subpixel models, whose spread is not measured.
    pub fn default_band_spread(&self, model: DispersionModel) -> BandSpread {
        match (self, model) {
            (Self::Default(_), DispersionModel::DispersedMask | DispersionModel::CrispCells) => {
                BandSpread::Uniform
            }
            _ => BandSpread::Point,
        }
    }

    /// A preset by name with its default settings and the nominal `stride`.
    pub fn by_name(name: &str, stride: f64) -> crate::error::Result<Self> {
        match name {
            "default" => Ok(Self::Default(DefaultPreset {
                stride,
                ..DefaultPreset::default()
            })),
            "paper" => Ok(Self::Paper(PaperPreset {
                stride,
                ..PaperPreset::default()
            })),
            other => Err(crate::error::CassiError::InvalidParameter {
                name: "preset",
                value: f64::NAN,
                reason: format!(
                    "unknown preset '{other}' (known: {})",
                    PRESET_NAMES.join(", ")
                ),
            }),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Self::Default(_) => "default",
            Self::Paper(_) => "paper",
        }
    }

    /// The preset holding the dispersion's curvature at `a2` px per band²
    /// (a camera design's value). Only the default preset models one; it
    /// refuses a curvature outside ±[`MAX_DISPERSION_A2`](crate::params::MAX_DISPERSION_A2).
    pub fn with_dispersion_a2(self, a2: f64) -> crate::error::Result<Self> {
        crate::params::validate_curvature(a2)?;
        match self {
            Self::Default(p) => Ok(Self::Default(DefaultPreset {
                dispersion_a2: a2,
                ..p
            })),
            Self::Paper(_) if a2 != 0.0 => Err(crate::error::CassiError::InvalidParameter {
                name: "a2",
                value: a2,
                reason: "the paper preset models a straight dispersion; a curvature needs the \
                         default preset"
                    .into(),
            }),
            paper => Ok(paper),
        }
    }

    /// `rows` as the command line and Python spell it: a count of middle
    /// rows, or `all` (every row) — for [`Preset::with_search_rows`].
    pub fn search_rows_from_str(rows: &str) -> std::result::Result<Option<usize>, String> {
        if rows == "all" {
            return Ok(None);
        }
        match rows.parse::<usize>() {
            Ok(n) if n > 0 => Ok(Some(n)),
            _ => Err(format!("'{rows}': a number of rows above 0, or 'all'")),
        }
    }

    /// The preset with its search stages on `rows` middle rows of a taller
    /// frame (`None`: every row; [`DefaultPreset::search_rows`]). Only the
    /// default preset has them.
    pub fn with_search_rows(self, rows: Option<usize>) -> crate::error::Result<Self> {
        if rows == Some(0) {
            return Err(crate::error::CassiError::InvalidParameter {
                name: "search_rows",
                value: 0.0,
                reason: "the rows the search stages run on: 1 or more (or every row)".into(),
            });
        }
        match self {
            Self::Default(p) => Ok(Self::Default(DefaultPreset {
                search_rows: rows,
                ..p
            })),
            Self::Paper(_) => Err(crate::error::CassiError::InvalidParameter {
                name: "search_rows",
                value: rows.map_or(f64::INFINITY, |r| r as f64),
                reason: "the paper preset's grids run on every row; a search band needs the \
                         default preset"
                    .into(),
            }),
        }
    }

    /// The preset without its [`BlurPass`] (the default preset's last stage
    /// since stop 41): σ as the scene fit leaves it. The paper preset has
    /// none and is returned as it is.
    pub fn without_blur_pass(self) -> Self {
        match self {
            Self::Default(p) => Self::Default(DefaultPreset {
                blur_pass: None,
                ..p
            }),
            paper => paper,
        }
    }

    /// The preset with the [`BlurPass`] on (σ refitted last on the crisp-cell
    /// model with GAP-TV's texture: σ nearer on blurred instruments and
    /// smooth scenes; see the README) — the default preset's own since
    /// stop 41. Only the default preset has one.
    pub fn with_blur_pass(self) -> crate::error::Result<Self> {
        match self {
            Self::Default(p) => Ok(Self::Default(DefaultPreset {
                blur_pass: Some(BlurPass::default()),
                ..p
            })),
            Self::Paper(_) => Err(crate::error::CassiError::InvalidParameter {
                name: "blur_pass",
                value: 1.0,
                reason: "the paper preset does not fit a blur; the blur pass needs the default \
                         preset"
                    .into(),
            }),
        }
    }

    /// The preset with the dispersion's curvature a2 fitted in the scene
    /// fit's fine pass ([`FinePassFree::GeometryAndCurvature`]: after its
    /// straight refit, from the value the preset holds —
    /// [`Preset::with_dispersion_a2`], 0 by default): for a prism whose
    /// dispersion is not linear in the band index. A local refinement: on
    /// the benchmark it reaches an instrument's a2 from 0.002 px/band² off
    /// in 21 of 35 held-out cases, from 0.006 off rarely (README: Fitting
    /// the curvature). Only the default preset's fine pass can.
    pub fn with_fitted_curvature(self) -> crate::error::Result<Self> {
        let refused = |reason: &str| crate::error::CassiError::InvalidParameter {
            name: "fit_curvature",
            value: 1.0,
            reason: reason.into(),
        };
        match self {
            Self::Default(mut p) => {
                let pass = p
                    .scene_fit
                    .as_mut()
                    .and_then(|s| s.fine_pass.as_mut())
                    .ok_or_else(|| {
                        refused(
                            "the curvature is fitted in the scene fit's fine pass, which is off",
                        )
                    })?;
                pass.free = FinePassFree::GeometryAndCurvature;
                // in both of the pass's runs, as it was measured (stop 53):
                // an off-grid run's own free set would hold a2
                pass.off_grid_run = None;
                Ok(Self::Default(p))
            }
            Self::Paper(_) => Err(refused(
                "the paper preset models a straight dispersion; fitting a curvature needs the \
                 default preset",
            )),
        }
    }

    /// The preset with the [`RidgeProbes`] on (after the scene fit's fine
    /// pass: its objective profiled along the dx–a1 and dy–α ridges, the
    /// second dips refitted, the ends that score within the margin
    /// reported and reached by the stated errors). Only the default preset's scene fit has them.
    pub fn with_ridge_probes(self) -> crate::error::Result<Self> {
        match self {
            Self::Default(p) => Ok(Self::Default(DefaultPreset {
                ridge_probes: Some(RidgeProbes::default()),
                ..p
            })),
            Self::Paper(_) => Err(crate::error::CassiError::InvalidParameter {
                name: "ridge_probes",
                value: 1.0,
                reason: "the paper preset has no scene fit to probe from; the ridge probes \
                         need the default preset"
                    .into(),
            }),
        }
    }

    /// An error unless this preset can hold band offsets
    /// ([`CalibrationProblem::with_band_offsets`]): the paper preset's
    /// unrolled gradients know a1·k + a2·k² alone. Callers check it before
    /// loading data; [`calibrate`] checks it again.
    pub fn check_band_offsets(&self) -> crate::error::Result<()> {
        match self {
            Self::Default(_) => Ok(()),
            Self::Paper(_) => Err(crate::error::CassiError::Meaningless {
                what: "band offsets with the paper preset".into(),
                reason: "its gradient stages differentiate a1·k + a2·k² alone; hold a band \
                         table with the default preset"
                    .into(),
            }),
        }
    }

    /// An error unless this preset can spread the bands' light
    /// ([`CalibrationProblem::with_band_spread`]): the paper preset's
    /// unrolled gradients know a sharp point per band alone. Checked as
    /// [`Self::check_band_offsets`] is.
    pub fn check_band_spread(&self, spread: BandSpread) -> crate::error::Result<()> {
        match self {
            Self::Paper(_) if spread != BandSpread::Point => {
                Err(crate::error::CassiError::Meaningless {
                    what: format!("a {} band spread with the paper preset", spread.name()),
                    reason: "its gradient stages differentiate a sharp point per band; spread \
                             the bands with the default preset"
                        .into(),
                })
            }
            _ => Ok(()),
        }
    }

    /// How many of the preset's first recorded stages are its search, before
    /// any refinement (the ablation's search-only variant stops there).
    pub fn search_stages(&self) -> usize {
        match self {
            Self::Default(_) => 1,
            Self::Paper(_) => 2,
        }
    }

    /// What the ablation calls this preset's search-only variant.
    pub fn search_label(&self) -> &'static str {
        match self {
            Self::Default(_) => "first stage only",
            Self::Paper(_) => "grid only (stages 0–1)",
        }
    }
}

/// Runs `preset` on `problem`; `on_stage` sees each stage as it finishes,
/// on the calling thread (the work itself runs on a rayon worker: `on_pool.rs`).
pub fn calibrate(
    problem: &CalibrationProblem<'_>,
    preset: &Preset,
    on_stage: &mut dyn FnMut(&StageReport),
) -> crate::error::Result<Calibration> {
    if problem.band_offsets().is_some() {
        preset.check_band_offsets()?;
    }
    preset.check_band_spread(problem.band_spread())?;
    // on a rayon worker: see `on_pool.rs`
    on_pool::on_pool(
        |on_stage| match preset {
            Preset::Default(p) => calibrate_default(problem, p, on_stage),
            Preset::Paper(p) => calibrate_paper(problem, p, on_stage),
        },
        on_stage,
    )
}
