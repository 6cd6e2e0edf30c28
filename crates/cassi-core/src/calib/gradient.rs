//! Exact gradients of the proxy score (paper §4.1–4.2) through the unrolled
//! solver, by forward mode: each parameter p carries a tangent cube ẋ = ∂x/∂p
//! through every iteration of
//! ```text
//! x₀ = Aᵀ(y Φ⁻¹);  x ← clamp(G(x + Aᵀ((y − A x) Φ⁻¹)), 0, 1);  score = Σ (y − A x)² / N
//! ```
//! so a gradient costs about 1 + 2P score evaluations for P parameters and
//! needs no stored iterates (a hand-written reverse pass would cost ~3 and
//! keep every iterate). The paper's Adam stages move one to three
//! parameters at a time, where forward mode is as cheap or cheaper.
//!
//! How each parameter moves the operator A (and Φ = diag A Aᵀ):
//! - dx, dy, θ move the warped mask m̃; A is linear in the mask, so
//!   ∂A/∂p is the operator with mask ∂m̃/∂p (exact bilinear derivatives).
//! - a1, α move the band offsets. `Subpixel`: A is linear in the bilinear
//!   tap weights, so ∂A/∂p is the operator with the weights' derivatives
//!   (exact). `Rounded`: the offsets are rounded, so the straight-through
//!   estimator (paper Eq. 4) treats round() as the identity: a band image
//!   shifted by d has derivative −(central difference along the shift) —
//!   the exact derivative of the model whose integer shifts are replaced by
//!   linear interpolation, at the integer offsets.

use rayon::prelude::*;

use super::score::{CalibrationProblem, EPS_FRACTION, ProxyParams, StepNorm, fit_to_model};
use super::smooth::{gaussian_taps, smooth_step};
use crate::cube::Frame;
use crate::error::Result;
use crate::linop::LinearOperator;
use crate::optics::{CassiOperator, Dispersion, warp_mask_with_derivatives};
use crate::params::Mismatch;

/// A component of ψ (the registry lives with the parameters).
pub use crate::params::Parameter;

/// ∂A/∂p for one parameter.
enum OperatorDerivative {
    /// An operator of A's form (mask or tap-weight derivative).
    Linear(CassiOperator),
    /// Rounded offsets through the STE: band k moves at (`col[k]`, `row[k]`)
    /// pixels per unit of p.
    StraightThrough { col: Vec<f32>, row: Vec<f32> },
}

/// Elements per parallel task in the element-wise passes.
const CHUNK: usize = 1 << 14;

/// Buffers the derivative operators borrow.
struct Scratch {
    cube: Vec<f32>,
    meas: Vec<f32>,
}

impl OperatorDerivative {
    fn new(a: &CassiOperator, d_mask: Option<Frame>, p: Parameter) -> Self {
        if let Some(m) = d_mask {
            return Self::Linear(a.derivative(m, a.dispersion().clone()));
        }
        let disp = a.dispersion();
        let rates: Vec<(f64, f64)> = (0..disp.bands())
            .map(|k| match p {
                Parameter::A1 => disp.offset_rate_a1(k),
                Parameter::A2 => disp.offset_rate_a2(k),
                _ => disp.offset_rate_alpha_deg(k),
            })
            .collect();
        match disp.weight_derivatives(&rates) {
            Some(d) => Self::Linear(a.derivative(a.mask().clone(), d)),
            None => Self::StraightThrough {
                col: rates.iter().map(|r| r.0 as f32).collect(),
                row: rates.iter().map(|r| r.1 as f32).collect(),
            },
        }
    }

    /// out = (∂A/∂p) x.
    fn apply(&self, a: &CassiOperator, x: &[f32], out: &mut [f32], s: &mut Scratch) {
        match self {
            Self::Linear(d) => d.apply(x, out),
            Self::StraightThrough { col, row } => {
                out.fill(0.0);
                let (_, det) = a.measurement_shape();
                for (rates, along_rows) in [(col, false), (row, true)] {
                    if rates.iter().all(|&v| v == 0.0) {
                        continue;
                    }
                    scale_bands(x, rates, &mut s.cube);
                    a.apply(&s.cube, &mut s.meas);
                    central_difference_add(&s.meas, det, along_rows, -1.0, out);
                }
            }
        }
    }

    /// out = (∂Aᵀ/∂p) r.
    fn adjoint(&self, a: &CassiOperator, r: &[f32], out: &mut [f32], s: &mut Scratch) {
        match self {
            Self::Linear(d) => d.adjoint(r, out),
            Self::StraightThrough { col, row } => {
                out.fill(0.0);
                let (_, det) = a.measurement_shape();
                for (rates, along_rows) in [(col, false), (row, true)] {
                    if rates.iter().all(|&v| v == 0.0) {
                        continue;
                    }
                    s.meas.fill(0.0);
                    central_difference_add(r, det, along_rows, 1.0, &mut s.meas);
                    a.adjoint(&s.meas, &mut s.cube);
                    let band = out.len() / rates.len();
                    for ((o, c), &rate) in out
                        .chunks_mut(band)
                        .zip(s.cube.chunks(band))
                        .zip(rates.iter())
                    {
                        o.iter_mut().zip(c).for_each(|(o, &c)| *o += rate * c);
                    }
                }
            }
        }
    }

    /// ∂Φ/∂p of the step's normaliser (see `score::StepNorm`), before ε̄,
    /// and ∂ε̄/∂p: Φ = diag(A Aᵀ) (ε̄ = 0), or with `row_sums` Φ = A Aᵀ 𝟙
    /// and ε̄ = its mean × `EPS_FRACTION`.
    fn phi(&self, a: &CassiOperator, row_sums: bool, s: &mut Scratch) -> (Vec<f32>, f64) {
        if row_sums {
            // Φ̇ = Ȧ (Aᵀ𝟙) + A (Ȧᵀ𝟙)
            let ones = vec![1.0f32; a.range_len()];
            let mut back = vec![0.0f32; a.domain_len()];
            a.adjoint(&ones, &mut back);
            let mut out = vec![0.0f32; a.range_len()];
            self.apply(a, &back, &mut out, s);
            self.adjoint(a, &ones, &mut back, s);
            a.apply(&back, &mut s.meas);
            out.iter_mut().zip(&s.meas).for_each(|(o, &v)| *o += v);
            let mean = out.iter().map(|&v| v as f64).sum::<f64>() / out.len() as f64;
            return (out, EPS_FRACTION as f64 * mean);
        }
        let phi = match self {
            Self::Linear(d) => a
                .diag_product(d)
                .into_vec()
                .into_iter()
                .map(|v| 2.0 * v)
                .collect(),
            Self::StraightThrough { col, row } => {
                // Φ = Σ_k shift_k(m²) = A applied to copies of m
                let mask = a.mask().as_slice();
                let ones: Vec<f32> = (0..col.len()).flat_map(|_| mask.iter().copied()).collect();
                let mut out = vec![0.0; a.range_len()];
                let (_, det) = a.measurement_shape();
                for (rates, along_rows) in [(col, false), (row, true)] {
                    if rates.iter().all(|&v| v == 0.0) {
                        continue;
                    }
                    scale_bands(&ones, rates, &mut s.cube);
                    a.apply(&s.cube, &mut s.meas);
                    central_difference_add(&s.meas, det, along_rows, -1.0, &mut out);
                }
                out
            }
        };
        (phi, 0.0)
    }
}

/// dst = x with band k scaled by rates[k].
fn scale_bands(x: &[f32], rates: &[f32], dst: &mut [f32]) {
    let band = x.len() / rates.len();
    for ((d, s), &rate) in dst.chunks_mut(band).zip(x.chunks(band)).zip(rates) {
        d.iter_mut().zip(s).for_each(|(d, &v)| *d = rate * v);
    }
}

/// out += sign · (v[i+1] − v[i−1]) / 2 along columns (or rows) of a frame
/// `cols` wide, zero beyond the frame.
fn central_difference_add(v: &[f32], cols: usize, along_rows: bool, sign: f32, out: &mut [f32]) {
    let rows = v.len() / cols;
    let h = 0.5 * sign;
    for r in 0..rows {
        let o = &mut out[r * cols..(r + 1) * cols];
        if along_rows {
            for (c, o) in o.iter_mut().enumerate() {
                let next = if r + 1 < rows {
                    v[(r + 1) * cols + c]
                } else {
                    0.0
                };
                let prev = if r > 0 { v[(r - 1) * cols + c] } else { 0.0 };
                *o += h * (next - prev);
            }
        } else {
            let row = &v[r * cols..(r + 1) * cols];
            for c in 0..cols {
                let next = if c + 1 < cols { row[c + 1] } else { 0.0 };
                let prev = if c > 0 { row[c - 1] } else { 0.0 };
                o[c] += h * (next - prev);
            }
        }
    }
}

impl CalibrationProblem<'_> {
    /// score(ψ) and its exact gradient along `params` (same order).
    pub fn score_and_gradient(
        &self,
        psi: &Mismatch,
        proxy: &ProxyParams,
        params: &[Parameter],
    ) -> Result<(f64, Vec<f64>)> {
        self.check_cancelled()?;
        psi.validate()?;
        // The unrolled forward-mode derivatives are written for the sharp
        // operator; a blurred model is fitted by the derivative-free stages.
        if psi.blur_sigma_px != 0.0 || params.contains(&Parameter::BlurSigmaPx) {
            return Err(crate::error::CassiError::InvalidParameter {
                name: "blur_sigma_px",
                value: psi.blur_sigma_px,
                reason: "exact score gradients are available for the sharp model only".into(),
            });
        }
        if self.band_offsets().is_some() {
            return Err(crate::error::CassiError::Meaningless {
                what: "exact score gradients with band offsets held".into(),
                reason:
                    "the unrolled derivatives are written for a1·k + a2·k²; use the default preset"
                        .into(),
            });
        }
        let dispersion = Dispersion::new(self.bands(), psi.dispersion(), self.model())?;
        let warp = warp_mask_with_derivatives(self.nominal_mask(), &psi.pose());
        let a = CassiOperator::new(warp.value.clone(), dispersion)?;
        let derivatives: Vec<OperatorDerivative> = params
            .iter()
            .map(|&p| {
                let d_mask = match p {
                    Parameter::Dx => Some(warp.d_dx.clone()),
                    Parameter::Dy => Some(warp.d_dy.clone()),
                    Parameter::ThetaDeg => Some(warp.d_theta_deg.clone()),
                    Parameter::A1 | Parameter::AlphaDeg | Parameter::A2 => None,
                    Parameter::BlurSigmaPx => unreachable!("refused above"),
                };
                OperatorDerivative::new(&a, d_mask, p)
            })
            .collect();
        let (m, n) = (a.range_len(), a.domain_len());
        let (_, h, w) = a.cube_shape();
        let size = self.measurement.as_slice().len() as f64;
        let (y, outside) = fit_to_model(self.measurement, a.measurement_shape().1);
        let norm = StepNorm::new(&a);
        let ip = &norm.inv_phi;
        let eps = norm.line_search;
        let mut s = Scratch {
            cube: vec![0.0; n],
            meas: vec![0.0; m],
        };
        // ∂Φ⁻¹/∂p = −Φ̇ Φ⁻², and ε̇ when the step is line-searched
        let (ip_dot, eps_dot): (Vec<Vec<f32>>, Vec<f64>) = derivatives
            .iter()
            .map(|d| {
                let (phi_dot, e) = d.phi(&a, eps.is_some(), &mut s);
                let ipd = phi_dot
                    .into_iter()
                    .zip(ip)
                    .map(|(pd, &i)| -(pd + e as f32) * i * i)
                    .collect();
                (ipd, e)
            })
            .unzip();
        let taps = gaussian_taps(proxy.sigma);
        let mut p = vec![0.0f32; m];
        let mut res = vec![0.0f32; m];
        let mut yh = vec![0.0f32; m];
        let mut p_dot = vec![0.0f32; m];
        let mut yh_dot = vec![0.0f32; m];
        let mut step = vec![0.0f32; n];
        let mut scaled = vec![0.0f32; n];
        let mut step_dot = vec![0.0f32; n];
        let mut x = vec![0.0f32; n];
        let mut x_next = vec![0.0f32; n];
        let mut x_dot = vec![vec![0.0f32; n]; params.len()];

        // x₀ = τ₀ Aᵀ(y Φ⁻¹),  ẋ₀ = τ₀ (Ȧᵀ p + Aᵀ ṗ) + τ̇₀ Aᵀ p
        for i in 0..m {
            p[i] = y[i] * ip[i];
        }
        a.adjoint(&p, &mut step);
        let tau0 = norm.tau(&y, &p, &step);
        let search0 = LineSearch::at(eps, &p, &step);
        for ((d, xd), (ipd, &e_dot)) in derivatives
            .iter()
            .zip(&mut x_dot)
            .zip(ip_dot.iter().zip(&eps_dot))
        {
            for i in 0..m {
                p_dot[i] = y[i] * ipd[i];
            }
            d.adjoint(&a, &p, &mut step_dot, &mut s);
            a.adjoint(&p_dot, &mut s.cube);
            step_dot.iter_mut().zip(&s.cube).for_each(|(v, &t)| *v += t);
            // res = y does not depend on ψ
            let td = search0.tau_dot(
                tau0,
                || dot(&y, &p_dot),
                &p,
                &step,
                &p_dot,
                &step_dot,
                e_dot,
            );
            for ((v, &sd), &st) in xd.iter_mut().zip(&step_dot).zip(&step) {
                *v = tau0 * sd + td * st;
            }
        }
        x.iter_mut().zip(&step).for_each(|(v, &st)| *v = tau0 * st);

        // ẏ = Ȧ x + A ẋ
        let model_dot =
            |d: &OperatorDerivative, x: &[f32], xd: &[f32], yh_dot: &mut [f32], s: &mut Scratch| {
                d.apply(&a, x, yh_dot, s);
                a.apply(xd, &mut s.meas);
                yh_dot.iter_mut().zip(&s.meas).for_each(|(v, &t)| *v += t);
            };
        for _ in 0..proxy.iterations {
            a.apply(&x, &mut yh);
            for i in 0..m {
                res[i] = y[i] - yh[i];
                p[i] = res[i] * ip[i];
            }
            a.adjoint(&p, &mut step);
            let tau = norm.tau(&res, &p, &step);
            let search = LineSearch::at(eps, &p, &step);
            x_next.copy_from_slice(&x);
            if tau == 1.0 {
                smooth_step(&mut x_next, Some(&step), h, w, &taps, true);
            } else {
                scaled
                    .iter_mut()
                    .zip(&step)
                    .for_each(|(v, &st)| *v = tau * st);
                smooth_step(&mut x_next, Some(&scaled), h, w, &taps, true);
            }
            for ((d, xd), (ipd, &e_dot)) in derivatives
                .iter()
                .zip(&mut x_dot)
                .zip(ip_dot.iter().zip(&eps_dot))
            {
                model_dot(d, &x, xd, &mut yh_dot, &mut s);
                // ṙes = −ẏ;  ṗ = ṙes Φ⁻¹ + res ∂Φ⁻¹
                for i in 0..m {
                    p_dot[i] = -yh_dot[i] * ip[i] + res[i] * ipd[i];
                }
                // ṡ = Ȧᵀ p + Aᵀ ṗ
                d.adjoint(&a, &p, &mut step_dot, &mut s);
                a.adjoint(&p_dot, &mut s.cube);
                step_dot
                    .par_chunks_mut(CHUNK)
                    .zip(s.cube.par_chunks(CHUNK))
                    .for_each(|(v, t)| v.iter_mut().zip(t).for_each(|(v, &t)| *v += t));
                // ṙes = −ẏ
                let num_dot = || dot(&res, &p_dot) - dot(&yh_dot, &p);
                let td = search.tau_dot(tau, num_dot, &p, &step, &p_dot, &step_dot, e_dot);
                // ẋ ← G(ẋ + τ ṡ + τ̇ s), zero where the clamp bound (it
                // passes no derivative there)
                s.cube
                    .par_chunks_mut(CHUNK)
                    .zip(step_dot.par_chunks(CHUNK).zip(step.par_chunks(CHUNK)))
                    .for_each(|(t, (sd, st))| {
                        for ((t, &sd), &st) in t.iter_mut().zip(sd).zip(st) {
                            *t = tau * sd + td * st;
                        }
                    });
                smooth_step(xd, Some(&s.cube), h, w, &taps, false);
                xd.par_chunks_mut(CHUNK)
                    .zip(x_next.par_chunks(CHUNK))
                    .for_each(|(v, xn)| {
                        for (v, &xn) in v.iter_mut().zip(xn) {
                            if xn <= 0.0 || xn >= 1.0 {
                                *v = 0.0;
                            }
                        }
                    });
            }
            std::mem::swap(&mut x, &mut x_next);
        }
        a.apply(&x, &mut yh);
        let inside: f64 = y
            .iter()
            .zip(&yh)
            .map(|(&a, &b)| ((a - b) as f64).powi(2))
            .sum();
        let mut gradient = Vec::with_capacity(params.len());
        for (d, xd) in derivatives.iter().zip(&x_dot) {
            model_dot(d, &x, xd, &mut yh_dot, &mut s);
            let g: f64 = y
                .iter()
                .zip(&yh)
                .zip(&yh_dot)
                .map(|((&a, &b), &bd)| (a - b) as f64 * bd as f64)
                .sum();
            gradient.push(-2.0 * g / size);
        }
        Ok(((inside + outside) / size, gradient))
    }
}

/// What τ̇ of the line search τ = ⟨res, p⟩ / (‖Aᵀp‖² + ε̄‖p‖²) needs from
/// one step, computed once for all parameters; `None` without line search
/// (τ ≡ 1).
struct LineSearch(Option<(f64, f64, f64)>);

impl LineSearch {
    /// (ε̄, the denominator, ‖p‖²) at `p`, `step` = Aᵀp.
    fn at(eps: Option<f32>, p: &[f32], step: &[f32]) -> Self {
        Self(eps.map(|e| {
            let (e, pp) = (e as f64, dot(p, p));
            (e, dot(step, step) + e * pp, pp)
        }))
    }

    /// τ̇ given the numerator's derivative (evaluated only with a line
    /// search), ṗ, ṡ = d(Aᵀp) and ε̄̇.
    #[allow(clippy::too_many_arguments)]
    fn tau_dot(
        &self,
        tau: f32,
        num_dot: impl FnOnce() -> f64,
        p: &[f32],
        step: &[f32],
        p_dot: &[f32],
        step_dot: &[f32],
        e_dot: f64,
    ) -> f32 {
        let Some((e, den, pp)) = self.0 else {
            return 0.0;
        };
        if den <= 0.0 {
            return 0.0;
        }
        let den_dot = 2.0 * dot(step, step_dot) + e_dot * pp + 2.0 * e * dot(p, p_dot);
        ((num_dot() - tau as f64 * den_dot) / den) as f32
    }
}

fn dot(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(&u, &v)| u as f64 * v as f64).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::score::{StepNorm, residual_with};
    use crate::cube::{Mask, Measurement};
    use crate::optics::{DispersionModel, SimulationSpec, simulate, warp_mask};
    use crate::params::DispersionParams;
    use crate::synth::{SceneSpec, random_binary_mask, synthetic_scene};

    const PROXY: ProxyParams = ProxyParams {
        iterations: 6,
        sigma: 0.7,
    };

    fn setup(model: DispersionModel) -> (Measurement, Mask) {
        let scene = synthetic_scene(&SceneSpec {
            rows: 40,
            cols: 48,
            wavelengths_nm: (0..6).map(|k| 450.0 + 40.0 * k as f64).collect(),
            seed: 3,
        })
        .unwrap();
        let mask = random_binary_mask(40, 48, 0.5, 9).unwrap();
        let truth = Mismatch {
            dx: 0.6,
            dy: -0.4,
            theta_deg: 0.3,
            a1: 2.04,
            alpha_deg: 0.5,
            ..Mismatch::nominal(2.0)
        };
        let spec = SimulationSpec {
            mismatch: truth,
            model,
            noise: None,
        };
        (simulate(&scene, &mask, &spec).unwrap(), mask)
    }

    fn problem_of<'a>(
        y: &'a Measurement,
        mask: &'a Mask,
        model: DispersionModel,
    ) -> CalibrationProblem<'a> {
        CalibrationProblem::nominal(y, mask, 6, 2.0, model).unwrap()
    }

    /// A candidate away from the truth on every axis, with no rounded band
    /// offset near a rounding tie.
    const AT: Mismatch = Mismatch {
        dx: 0.37,
        dy: -0.21,
        theta_deg: 0.23,
        a1: 2.03,
        alpha_deg: 0.4,
        ..Mismatch::nominal(2.0)
    };

    fn assert_close(what: &str, got: f64, want: f64) {
        let tol = 0.02 * want.abs() + 1e-9;
        assert!(
            (got - want).abs() <= tol,
            "{what}: gradient {got:e}, finite difference {want:e}"
        );
        assert!(
            want.abs() > 1e-7,
            "{what}: finite difference {want:e} too small to test"
        );
    }

    #[test]
    fn mask_pose_gradients_match_finite_differences_for_both_models() {
        for model in [DispersionModel::Rounded, DispersionModel::Subpixel] {
            let (y, mask) = setup(model);
            let problem = problem_of(&y, &mask, model);
            let params = [Parameter::Dx, Parameter::Dy, Parameter::ThetaDeg];
            let (s, g) = problem.score_and_gradient(&AT, &PROXY, &params).unwrap();
            assert!((s - problem.score(&AT, &PROXY).unwrap()).abs() <= 1e-6 * s);
            for (p, gp) in params.iter().zip(g) {
                let h = 2e-3;
                let at = |v: f64| {
                    let mut m = AT;
                    p.set(&mut m, p.get(&AT) + v);
                    problem.score(&m, &PROXY).unwrap()
                };
                let fd = (at(h) - at(-h)) / (2.0 * h);
                assert_close(&format!("{model:?} {}", p.name()), gp, fd);
            }
        }
    }

    #[test]
    fn subpixel_dispersion_gradients_are_exact() {
        let model = DispersionModel::Subpixel;
        let (y, mask) = setup(model);
        let problem = problem_of(&y, &mask, model);
        let params = [Parameter::A1, Parameter::AlphaDeg, Parameter::A2];
        let (_, g) = problem.score_and_gradient(&AT, &PROXY, &params).unwrap();
        for ((p, gp), h) in params.iter().zip(g).zip([1e-4, 1e-2, 1e-5]) {
            let at = |v: f64| {
                let mut m = AT;
                p.set(&mut m, p.get(&AT) + v);
                problem.score(&m, &PROXY).unwrap()
            };
            assert_close(p.name(), gp, (at(h) - at(-h)) / (2.0 * h));
        }
    }

    /// The rounded model's a1 and α gradients (straight-through) are the
    /// exact derivatives of the relaxed model in which each band's rounded
    /// offset moves continuously, t·(∂offset/∂p), by linear interpolation
    /// (and Φ = Σ_k shift_k(m²) with the same interpolation, inverted only
    /// where light arrives at t = 0).
    #[test]
    fn straight_through_gradients_match_the_relaxed_model() {
        let model = DispersionModel::Rounded;
        let (y, mask) = setup(model);
        let problem = problem_of(&y, &mask, model);
        let params = [Parameter::A1, Parameter::AlphaDeg];
        let (_, g) = problem.score_and_gradient(&AT, &PROXY, &params).unwrap();
        let warped = warp_mask(&mask, &AT.pose());
        let base = Dispersion::new(6, AT.dispersion(), model).unwrap();
        let base_op = CassiOperator::new(warped.clone(), base.clone()).unwrap();
        let base_det = base_op.measurement_shape().1;
        let base_phi = base_op.diag_aat().into_vec();
        for (p, gp) in params.iter().zip(g) {
            let relaxed = |t: f64| {
                let offsets = (0..6)
                    .map(|k| {
                        let (dc, dr) = base.offset(k);
                        let (rc, rr) = match p {
                            Parameter::A1 => base.offset_rate_a1(k),
                            _ => base.offset_rate_alpha_deg(k),
                        };
                        (dc.round_ties_even() + t * rc, dr.round_ties_even() + t * rr)
                    })
                    .collect();
                let params = DispersionParams {
                    a1: 2.0,
                    alpha_deg: 0.0,
                    a2: 0.0,
                };
                let disp =
                    Dispersion::from_offsets(params, offsets, DispersionModel::Subpixel).unwrap();
                let op = CassiOperator::new(warped.clone(), disp).unwrap();
                let copies: Vec<f32> = (0..6).flat_map(|_| warped.as_slice().to_vec()).collect();
                let mut phi = vec![0.0; op.range_len()];
                op.apply(&copies, &mut phi);
                // Φ⁻¹ stays 0 where no light arrived at t = 0 (there 1/Φ
                // jumps from 0 to O(1/t): not differentiable at all)
                let det = op.measurement_shape().1;
                let ip: Vec<f32> = phi
                    .iter()
                    .enumerate()
                    .map(|(i, &v)| {
                        let (r, c) = (i / det, i % det);
                        let lit = c < base_det && base_phi[r * base_det + c] > 0.0;
                        if lit { 1.0 / v } else { 0.0 }
                    })
                    .collect();
                let (yf, outside) = fit_to_model(&y, op.measurement_shape().1);
                let norm = StepNorm {
                    inv_phi: ip,
                    line_search: None,
                };
                let (_, h, w) = op.cube_shape();
                residual_with(
                    &op,
                    Some(&op),
                    (h, w),
                    &yf,
                    outside,
                    y.as_slice().len(),
                    &norm,
                    &PROXY,
                )
            };
            // the relaxed model bends sharply within ~1e-3 px of t = 0 (Φ is
            // small at some pixels), so the step moves the farthest band by
            // only ~5e-5 px (a1) or ~2e-5 px (α)
            let h = if *p == Parameter::A1 { 1e-5 } else { 1e-4 };
            assert_close(p.name(), gp, (relaxed(h) - relaxed(-h)) / (2.0 * h));
        }
    }
}
