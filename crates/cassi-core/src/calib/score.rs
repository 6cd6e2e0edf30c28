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

use super::smooth::{gaussian_taps, smooth_step};
use crate::cube::{Mask, Measurement};
use crate::error::{Result, shape_error};
use crate::linop::LinearOperator;
use crate::optics::{CassiOperator, DispersionModel};
use crate::params::Mismatch;

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

/// Everything fixed during a calibration: the measurement, the nominal mask,
/// the band count and the instrument model used for candidates.
pub struct CalibrationProblem<'a> {
    pub measurement: &'a Measurement,
    pub nominal_mask: &'a Mask,
    pub bands: usize,
    pub model: DispersionModel,
}

impl CalibrationProblem<'_> {
    pub fn validate(&self) -> Result<()> {
        self.measurement.check_finite("measurement")?;
        if self.measurement.rows() != self.nominal_mask.rows() {
            return Err(shape_error(
                "measurement rows",
                self.measurement.rows().to_string(),
                format!("{} (the mask's rows)", self.nominal_mask.rows()),
            ));
        }
        if self.measurement.cols() < self.nominal_mask.cols() {
            return Err(shape_error(
                "measurement cols",
                self.measurement.cols().to_string(),
                format!("at least {} (the mask's cols)", self.nominal_mask.cols()),
            ));
        }
        Ok(())
    }

    /// score(ψ) with the proxy `proxy`.
    pub fn score(&self, psi: &Mismatch, proxy: &ProxyParams) -> Result<f64> {
        let op = CassiOperator::with_mismatch(self.nominal_mask, self.bands, psi, self.model)?;
        Ok(proxy_residual(&op, self.measurement, proxy))
    }
}

/// The proxy reconstruction's residual for one operator (see the module doc).
pub fn proxy_residual(op: &CassiOperator, measurement: &Measurement, proxy: &ProxyParams) -> f64 {
    let (y, outside) = fit_to_model(measurement, op.measurement_shape().1);
    let size = measurement.as_slice().len();
    residual_with(op, &y, outside, size, &inverse_phi(op), proxy)
}

/// [`proxy_residual`] with the fitted measurement `y`, the energy `outside`
/// the model's columns, the measurement's pixel count and Φ⁻¹ given.
pub(crate) fn residual_with(
    op: &CassiOperator,
    y: &[f32],
    outside: f64,
    measurement_size: usize,
    inv_phi: &[f32],
    proxy: &ProxyParams,
) -> f64 {
    let (rows, det) = op.measurement_shape();
    let (_, h, w) = op.cube_shape();
    let taps = gaussian_taps(proxy.sigma);
    SCRATCH.with_borrow_mut(|scratch| {
        scratch.resize(rows * det, op.domain_len());
        let ProxyScratch { r, yh, step, x } = scratch;
        proxy_iterations(
            op,
            y,
            inv_phi,
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

/// Φ⁻¹ with Φ = diag(A Aᵀ), 0 where no light can arrive.
pub(crate) fn inverse_phi(op: &CassiOperator) -> Vec<f32> {
    op.diag_aat()
        .into_vec()
        .into_iter()
        .map(|d| if d > 0.0 { 1.0 / d } else { 0.0 })
        .collect()
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

/// Runs the unrolled proxy; leaves A x̂ in `yh`.
#[allow(clippy::too_many_arguments)]
fn proxy_iterations(
    op: &CassiOperator,
    y: &[f32],
    inv_phi: &[f32],
    taps: &[f32],
    iterations: usize,
    r: &mut [f32],
    yh: &mut [f32],
    step: &mut [f32],
    x: &mut [f32],
    h: usize,
    w: usize,
) {
    for (ri, (&yv, &ip)) in r.iter_mut().zip(y.iter().zip(inv_phi)) {
        *ri = yv * ip;
    }
    op.adjoint(r, x);
    for _ in 0..iterations {
        op.apply(x, yh);
        for i in 0..r.len() {
            r[i] = (y[i] - yh[i]) * inv_phi[i];
        }
        op.adjoint(r, step);
        smooth_step(x, Some(step), h, w, taps, true);
    }
    op.apply(x, yh);
}
