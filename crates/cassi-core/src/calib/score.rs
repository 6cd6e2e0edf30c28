//! The self-calibration objective (paper Eq. 3): for a candidate ψ, run a
//! short proxy reconstruction with the operator of ψ and measure how well it
//! explains the measurement.
//!
//! Proxy (unrolled, plain GAP with a Gaussian prior step):
//! ```text
//! x₀ = Aᵀ(y ⊙ Φ⁻¹);  x ← clamp(G_σ(x + Aᵀ((y − A x) ⊙ Φ⁻¹)), 0, 1)   (n times)
//! score(ψ) = Σ (y − A x)² / (H · W_meas)
//! ```
//! with Φ = diag(A Aᵀ). The residual is taken over the union of the measured
//! and the modelled detector columns (the narrower one zero-padded) and
//! divided by the fixed measurement size, so a candidate a1 that changes the
//! model's width can neither drop measured light nor win by shrinking the
//! denominator (the reference code's a1 defect).

use serde::{Deserialize, Serialize};

use super::smooth::{gaussian_taps, smooth_adjoint_step, smooth_step};
use crate::cube::{Mask, Measurement};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{CassiError, Result, shape_error};
use crate::linop::LinearOperator;
use crate::optics::{BandOffsets, BandSpread, CassiOperator, DispersionModel, ModelOperator};
use crate::params::Mismatch;
use crate::recon::{Method, MethodId, Model};
use crate::solvers::Silent;

/// Settings of the proxy reconstruction inside the score.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProxyParams {
    pub iterations: usize,
    /// σ of the per-band Gaussian step, pixels.
    pub sigma: f32,
}

impl Default for ProxyParams {
    fn default() -> Self {
        Self {
            iterations: 10,
            sigma: 0.7,
        }
    }
}

/// Everything fixed during a calibration: the measurement and the
/// instrument as designed — a [`Model`] with the nominal mask, the band
/// count, the nominal stride and the dispersion family the candidates use
/// (its mismatch is where the search starts from: the nominal one).
#[derive(Debug, Clone, Copy)]
pub struct CalibrationProblem<'a> {
    pub measurement: &'a Measurement,
    pub nominal: Model<'a>,
    /// Raised by the caller (another thread, a signal handler) to stop the
    /// calibration: every score after it fails at once and the calibration
    /// returns [`CassiError::Cancelled`](crate::CassiError::Cancelled).
    pub cancel: Option<&'a AtomicBool>,
}

impl<'a> CalibrationProblem<'a> {
    /// The measurement of the nominal instrument `nominal_mask` with `bands`
    /// bands dispersed `stride` px per band, fitted with `dispersion`.
    pub fn nominal(
        measurement: &'a Measurement,
        nominal_mask: &'a Mask,
        bands: usize,
        stride: f64,
        dispersion: DispersionModel,
    ) -> Result<Self> {
        Ok(Self {
            measurement,
            nominal: Model::nominal(nominal_mask, bands, stride, dispersion)?,
            cancel: None,
        })
    }

    /// The same problem, stopped when `flag` is raised.
    pub fn with_cancel(self, flag: &'a AtomicBool) -> Self {
        Self {
            cancel: Some(flag),
            ..self
        }
    }

    /// An error once the caller asked to stop.
    pub fn check_cancelled(&self) -> Result<()> {
        match self.cancel {
            Some(flag) if flag.load(Ordering::Relaxed) => Err(CassiError::Cancelled {
                what: "calibration".into(),
            }),
            _ => Ok(()),
        }
    }

    pub fn nominal_mask(&self) -> &'a Mask {
        self.nominal.nominal_mask()
    }

    pub fn bands(&self) -> usize {
        self.nominal.bands()
    }

    /// The dispersion family of the candidates.
    pub fn model(&self) -> DispersionModel {
        self.nominal.dispersion()
    }

    /// The same problem with its bands `offsets` off the straight
    /// dispersion, held in every candidate ([`BandOffsets`]).
    pub fn with_band_offsets(&self, offsets: &'a BandOffsets) -> Result<Self> {
        Ok(Self {
            nominal: self.nominal.with_band_offsets(offsets)?,
            ..*self
        })
    }

    /// The same problem with each band's light spread along the dispersion
    /// as `spread` says in every candidate ([`BandSpread`]).
    pub fn with_band_spread(&self, spread: BandSpread) -> Self {
        Self {
            nominal: self.nominal.with_band_spread(spread),
            ..*self
        }
    }

    /// The same problem holding what a calibration held beside ψ
    /// ([`Model::holding`]): a combination's snapshots refitted, say.
    pub fn holding(&self, offsets: Option<&'a BandOffsets>, spread: BandSpread) -> Result<Self> {
        Ok(Self {
            nominal: self.nominal.holding(offsets, spread)?,
            ..*self
        })
    }

    /// Where each band's light lies along the dispersion in the candidates.
    pub fn band_spread(&self) -> BandSpread {
        self.nominal.band_spread()
    }

    /// The bands' held departures from the straight dispersion, if any.
    pub fn band_offsets(&self) -> Option<&'a BandOffsets> {
        self.nominal.band_offsets()
    }

    /// The candidate ψ's forward operator (the family's, band offsets held):
    /// every stage builds its operators here.
    pub fn operator(&self, psi: &Mismatch) -> Result<ModelOperator> {
        self.nominal.operator_at(psi)
    }

    /// The candidate ψ's operator with band k moved a further `along[k]` px
    /// ([`Model::operator_shifted`]: offsets and spread held).
    pub fn operator_shifted(&self, psi: &Mismatch, along: &[f64]) -> Result<ModelOperator> {
        self.nominal.operator_shifted(psi, along)
    }

    /// The same problem fitted with another dispersion family.
    pub fn with_model(&self, dispersion: DispersionModel) -> Self {
        Self {
            nominal: self.nominal.with_dispersion(dispersion),
            ..*self
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.measurement.check_finite("measurement")?;
        if self.measurement.rows() != self.nominal_mask().rows() {
            return Err(shape_error(
                "measurement rows",
                self.measurement.rows().to_string(),
                format!("{} (the mask's rows)", self.nominal_mask().rows()),
            ));
        }
        if self.measurement.cols() < self.nominal_mask().cols() {
            return Err(shape_error(
                "measurement cols",
                self.measurement.cols().to_string(),
                format!("at least {} (the mask's cols)", self.nominal_mask().cols()),
            ));
        }
        Ok(())
    }

    /// score(ψ) with the proxy `proxy` (ψ's blur included).
    pub fn score(&self, psi: &Mismatch, proxy: &ProxyParams) -> Result<f64> {
        self.check_cancelled()?;
        let op = self.operator(psi)?;
        Ok(proxy_residual(&op, self.measurement, proxy))
    }
}

/// The proxy reconstruction's residual for one operator (see the module doc).
pub fn proxy_residual(op: &ModelOperator, measurement: &Measurement, proxy: &ProxyParams) -> f64 {
    let (y, outside) = fit_to_model(measurement, op.measurement_shape().1);
    let size = measurement.as_slice().len();
    let (_, h, w) = op.cube_shape();
    residual_with(
        op,
        op.sharp(),
        (h, w),
        &y,
        outside,
        size,
        &StepNorm::for_model(op),
        proxy,
    )
}

/// GAP-TV's reconstruction (bands × rows × cols) of the problem's
/// measurement in the nominal model moved to `at`, `iterations` iterations
/// (its defaults otherwise): a scene estimate far closer than the proxy's,
/// at the cost of a solve.
pub fn gap_tv_reconstruction(
    problem: &CalibrationProblem<'_>,
    at: &Mismatch,
    iterations: usize,
) -> Result<crate::cube::Cube> {
    let model = problem.nominal.with_mismatch(*at)?;
    let mut method = Method::defaults(MethodId::GapTv).expect("GAP-TV is iterative");
    if let Method::GapTv { gap, .. } = &mut method {
        gap.iterations = iterations;
    }
    Ok(method.solve(problem.measurement, &model, &mut Silent)?.cube)
}

/// The proxy's reconstruction x̂ (bands × rows × cols) for one operator.
pub(crate) fn proxy_reconstruction(
    op: &ModelOperator,
    measurement: &Measurement,
    proxy: &ProxyParams,
) -> Vec<f32> {
    let (y, _) = fit_to_model(measurement, op.measurement_shape().1);
    let (_, h, w) = op.cube_shape();
    let norm = StepNorm::for_model(op);
    let taps = gaussian_taps(proxy.sigma);
    SCRATCH.with_borrow_mut(|scratch| {
        scratch.resize(op.range_len(), op.domain_len());
        let ProxyScratch { r, yh, step, x } = scratch;
        proxy_iterations(
            op,
            op.sharp(),
            &y,
            &norm,
            &taps,
            proxy.iterations,
            r,
            yh,
            step,
            x,
            h,
            w,
        );
        x.clone()
    })
}

/// [`proxy_residual`] for an operator on `(rows, cols)` band images, with
/// the fitted measurement `y`, the energy `outside` the model's columns, the
/// measurement's pixel count and the step's normaliser given (`sharp`: see
/// [`proxy_iterations`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn residual_with(
    op: &dyn LinearOperator,
    sharp: Option<&CassiOperator>,
    (h, w): (usize, usize),
    y: &[f32],
    outside: f64,
    measurement_size: usize,
    norm: &StepNorm,
    proxy: &ProxyParams,
) -> f64 {
    let taps = gaussian_taps(proxy.sigma);
    SCRATCH.with_borrow_mut(|scratch| {
        scratch.resize(op.range_len(), op.domain_len());
        let ProxyScratch { r, yh, step, x } = scratch;
        proxy_iterations(
            op,
            sharp,
            y,
            norm,
            &taps,
            proxy.iterations,
            r,
            yh,
            step,
            x,
            h,
            w,
        );
        let inside: f64 = y
            .iter()
            .zip(yh.iter())
            .map(|(&a, &b)| ((a - b) as f64).powi(2))
            .sum();
        (inside + outside) / measurement_size as f64
    })
}

/// The measurement fitted to a model's `det` detector columns (cropped or
/// zero-padded), and the energy Σ y² of the measured columns beyond them.
pub(crate) fn fit_to_model(measurement: &Measurement, det: usize) -> (Vec<f32>, f64) {
    let rows = measurement.rows();
    let mut y = vec![0.0f32; rows * det];
    let keep = det.min(measurement.cols());
    let mut outside = 0.0f64;
    for r in 0..rows {
        let src = measurement.row(r);
        y[r * det..r * det + keep].copy_from_slice(&src[..keep]);
        outside += src[keep..]
            .iter()
            .map(|&v| v as f64 * v as f64)
            .sum::<f64>();
    }
    (y, outside)
}

/// The GAP step x ← x + τ Aᵀ Φ⁻¹ (y − A x). With integer offsets
/// (`Rounded`) A Aᵀ is diagonal: Φ = diag(A Aᵀ), τ = 1 makes each step an
/// exact projection. With split taps (`Subpixel`) A Aᵀ couples neighbouring
/// detector pixels and that step overshoots (Φ^{-½} A Aᵀ Φ^{-½} reaches
/// eigenvalues ≈ 2–4 for a row-and-column split): the proxy oscillated, and
/// the score at the true ψ was ~400× that at α = 0 (cave_feathers, paper
/// mismatch). There Φ = A Aᵀ 𝟙 + ε̄ (row sums of the non-negative A Aᵀ, which
/// majorise it by Gershgorin, so the step is stable), and τ is the exact line
/// search of ½‖y − A x‖² + ½ε̄‖p‖² along p = Φ⁻¹ r: the majoriser alone
/// shortens the step most where light is split most, which biased the score
/// toward unsplit operators (α → 0 with dy compensating); the line search
/// restores a full step at no extra operator cost. ε̄ = 5 % of the mean Φ
/// keeps τ bounded where a residual sits on barely-lit detector pixels.
/// A blurred model (and the crisp-cell model, blurred or not) couples
/// neighbours whatever its dispersion and gets the same majoriser and line
/// search.
/// ε̄ as a fraction of the mean Φ (see [`StepNorm`]).
pub(crate) const EPS_FRACTION: f32 = 0.05;

pub(crate) struct StepNorm {
    pub(crate) inv_phi: Vec<f32>,
    /// ε̄ when the step is line-searched (`Subpixel`).
    pub(crate) line_search: Option<f32>,
}

impl StepNorm {
    pub(crate) fn new(op: &CassiOperator) -> Self {
        let inv = |d: f32| if d > 0.0 { 1.0 / d } else { 0.0 };
        if op.dispersion().model() == DispersionModel::Rounded {
            return Self {
                inv_phi: op.diag_aat().into_vec().into_iter().map(inv).collect(),
                line_search: None,
            };
        }
        Self::majorised(op)
    }

    /// The normaliser of a model operator (see the type's doc).
    pub(crate) fn for_model(op: &ModelOperator) -> Self {
        match op {
            ModelOperator::Sharp(a) => Self::new(a),
            ModelOperator::Blurred(b) => Self::majorised(b),
            ModelOperator::Cells(c) => Self::majorised(c),
        }
    }

    /// Φ = A Aᵀ 𝟙 + ε̄ with the line search, for a non-negative `op`.
    fn majorised(op: &dyn LinearOperator) -> Self {
        let mut back = vec![0.0f32; op.domain_len()];
        op.adjoint(&vec![1.0f32; op.range_len()], &mut back);
        let mut phi = vec![0.0f32; op.range_len()];
        op.apply(&back, &mut phi);
        let eps =
            EPS_FRACTION * phi.iter().map(|&v| v as f64).sum::<f64>() as f32 / phi.len() as f32;
        Self {
            inv_phi: phi
                .into_iter()
                .map(|d| if d > 0.0 { 1.0 / (d + eps) } else { 0.0 })
                .collect(),
            line_search: Some(eps),
        }
    }

    /// τ for the step `step` = Aᵀ p, p = Φ⁻¹ `res` (1 without line search).
    pub(crate) fn tau(&self, res: &[f32], p: &[f32], step: &[f32]) -> f32 {
        let Some(eps) = self.line_search else {
            return 1.0;
        };
        let dot = |a: &[f32], b: &[f32]| {
            a.iter()
                .zip(b)
                .map(|(&u, &v)| u as f64 * v as f64)
                .sum::<f64>()
        };
        let den = dot(step, step) + eps as f64 * dot(p, p);
        if den > 0.0 {
            (dot(res, p) / den) as f32
        } else {
            1.0
        }
    }
}

/// The proxy's buffers, kept between evaluations: a calibration scores
/// hundreds of candidates of the same size, and fresh 7 MB cubes each time
/// cost more in page faults than the arithmetic.
#[derive(Default)]
struct ProxyScratch {
    r: Vec<f32>,
    yh: Vec<f32>,
    step: Vec<f32>,
    x: Vec<f32>,
}

impl ProxyScratch {
    fn resize(&mut self, m: usize, n: usize) {
        self.r.resize(m, 0.0);
        self.yh.resize(m, 0.0);
        self.step.resize(n, 0.0);
        self.x.resize(n, 0.0);
    }
}

thread_local! {
    static SCRATCH: std::cell::RefCell<ProxyScratch> = std::cell::RefCell::new(ProxyScratch::default());
}

/// Runs the unrolled proxy; leaves A x̂ in `yh`. `sharp` is `op` when it is
/// a CASSI operator: with τ = 1 its step is then computed inside the prior
/// step ([`smooth_adjoint_step`], the same numbers).
#[allow(clippy::too_many_arguments)]
fn proxy_iterations(
    op: &dyn LinearOperator,
    sharp: Option<&CassiOperator>,
    y: &[f32],
    norm: &StepNorm,
    taps: &[f32],
    iterations: usize,
    r: &mut [f32],
    yh: &mut [f32],
    step: &mut [f32],
    x: &mut [f32],
    h: usize,
    w: usize,
) {
    let inv_phi = &norm.inv_phi;
    for (ri, (&yv, &ip)) in r.iter_mut().zip(y.iter().zip(inv_phi)) {
        *ri = yv * ip;
    }
    op.adjoint(r, x);
    let tau = norm.tau(y, r, x);
    if tau != 1.0 {
        x.iter_mut().for_each(|v| *v *= tau);
    }
    for _ in 0..iterations {
        op.apply(x, yh);
        for i in 0..r.len() {
            yh[i] = y[i] - yh[i]; // yh holds the residual until the next apply
            r[i] = yh[i] * inv_phi[i];
        }
        if let (Some(sharp), None) = (sharp, norm.line_search) {
            smooth_adjoint_step(x, sharp, r, taps, true);
            continue;
        }
        op.adjoint(r, step);
        let tau = norm.tau(yh, r, step);
        if tau != 1.0 {
            step.iter_mut().for_each(|v| *v *= tau);
        }
        smooth_step(x, Some(step), h, w, taps, true);
    }
    op.apply(x, yh);
}
