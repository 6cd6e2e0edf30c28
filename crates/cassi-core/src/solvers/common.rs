//! Pieces shared by the solvers: problem checks and the fused vector passes.

use crate::error::{CassiError, Result, shape_error};
use crate::linop::{AatNormaliser, LinearOperator, NormaliserKind};

/// Checks y and the cube shape against the operator.
pub(crate) fn check_problem(
    op: &dyn LinearOperator,
    y: &[f32],
    shape: (usize, usize, usize),
) -> Result<()> {
    let (l, h, w) = shape;
    if l * h * w != op.domain_len() {
        return Err(shape_error(
            "cube shape for the solver",
            format!("({l}, {h}, {w}) = {} values", l * h * w),
            format!("{} values (the operator's domain)", op.domain_len()),
        ));
    }
    if y.len() != op.range_len() {
        return Err(shape_error(
            "measurement",
            format!("{} values", y.len()),
            format!("{} values (the operator's range)", op.range_len()),
        ));
    }
    if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        return Err(CassiError::NonFinite {
            what: "measurement".into(),
            value: y[i],
            location: format!("index {i}"),
        });
    }
    Ok(())
}

pub(crate) fn check_iterations(n: usize) -> Result<()> {
    if n == 0 {
        return Err(CassiError::InvalidParameter {
            name: "iterations",
            value: 0.0,
            reason: "a solver needs at least one iteration".into(),
        });
    }
    Ok(())
}

/// 1/d where d > 0, else 0: detector pixels no light reaches carry no information.
pub(crate) fn inverse_or_zero(d: &[f32]) -> Vec<f32> {
    d.iter()
        .map(|&v| if v > 0.0 { 1.0 / v } else { 0.0 })
        .collect()
}

pub(crate) fn norm_sq(v: &[f32]) -> f64 {
    v.iter().map(|&a| a as f64 * a as f64).sum()
}

/// Elements per parallel chunk of the element-wise passes (a few L2-sized
/// pieces per band; chunk sums are combined in a fixed order, so results do
/// not depend on the thread count).
pub(crate) const CHUNK: usize = 1 << 14;

/// Σ a·b over a slice with 8 independent f32 lanes (vectorisable), as f64.
#[inline]
pub(crate) fn lanes_dot(a: &[f32], b: &[f32]) -> f64 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let tail: f32 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    acc.iter().map(|&v| v as f64).sum::<f64>() + tail as f64
}

/// x ← max(x + τ·step, 0) (or without the clamp), in parallel chunks;
/// returns (‖τ·step‖², ‖x_new‖²). τ = 1 multiplies exactly, so an
/// un-searched step is bit-identical to x + step.
pub(crate) fn add_step(x: &mut [f32], step: &[f32], tau: f32, nonnegative: bool) -> (f64, f64) {
    use rayon::prelude::*;
    let sums: Vec<(f64, f64)> = x
        .par_chunks_mut(CHUNK)
        .zip(step.par_chunks(CHUNK))
        .map(|(xc, sc)| {
            for (xv, &s) in xc.iter_mut().zip(sc) {
                let v = *xv + tau * s;
                *xv = if nonnegative { v.max(0.0) } else { v };
            }
            (lanes_dot(sc, sc), lanes_dot(xc, xc))
        })
        .collect();
    let (s, x) = sums
        .iter()
        .fold((0.0, 0.0), |(a, b), &(s, x)| (a + s, b + x));
    (s * (tau as f64) * (tau as f64), x)
}

/// ‖v‖² in parallel chunks (fixed combination order).
pub(crate) fn par_norm_sq(v: &[f32]) -> f64 {
    use rayon::prelude::*;
    let sums: Vec<f64> = v.par_chunks(CHUNK).map(|c| lanes_dot(c, c)).collect();
    sums.iter().sum()
}

/// The data step's normaliser, prepared once per solve.
///
/// The step is x ← x + τ Aᵀ p with p = (Φ + ε)⁻¹ r for the residual (or
/// GAP's accelerated target) r. The exact step is x + Aᵀ z* with
/// (A Aᵀ + ε₀ I) z* = r (GAP: ε₀ = 0, the projection onto {A x = y}; ADMM:
/// ε₀ = γ, the closed-form x-update).
///
/// - [`NormaliserKind::Exact`] (Φ = A Aᵀ): τ = 1, ε = ε₀, and the step is
///   the exact one.
/// - [`NormaliserKind::Majoriser`] (Φ ⪰ A Aᵀ): τ = 1. Then
///   Φ^{-½} A Aᵀ Φ^{-½} ⪯ I, so the step never overshoots the exact one in
///   any direction (diag(A Aᵀ) with split taps reaches eigenvalues ≈ 2–4
///   there, and GAP-TV / ADMM-TV with the true subpixel model fell up to
///   ~7 dB below the nominal model: issue #13). We measured the exact line
///   search of the calibration proxy on top of it (τ ≥ 1 minimising
///   ½ zᵀ(A Aᵀ + ε₀ I)z − rᵀz along p, no extra operator call) and it is
///   worse for GAP-TV: it lengthens the step along the ill-conditioned
///   directions of A Aᵀ (neighbouring split taps), which amplifies noise
///   and model error; with the paper's mismatch, subpixel, 2× oversampled
///   measurement, 64×64×8: 8.6 dB with the search vs 18.2 dB without
///   (nominal model 13.8 dB). For ADMM-TV the two agree within 0.05 dB.
/// - [`NormaliserKind::Approximate`] (nothing known, e.g. diag(A Aᵀ) of a
///   general operator): τ is that exact line search, with ε = ε₀ for ADMM
///   and ε = 5 % of the mean Φ for GAP (a Tikhonov-damped projection, as
///   the calibration proxy): every step then moves closer to the exact
///   (damped) one whatever A Aᵀ is — safe, not tuned.
pub(crate) struct DataStep {
    /// 1 / (Φ + ε), 0 where GAP's Φ ≤ 0 (no light there).
    pub(crate) inv: Vec<f32>,
    /// The damping in the line search when τ is searched.
    pub(crate) line_search: Option<f64>,
}

/// ε of GAP's line-searched step, as a fraction of the mean Φ.
const GAP_DAMPING: f64 = 0.05;

impl DataStep {
    pub(crate) fn gap(n: AatNormaliser) -> Self {
        if n.kind != NormaliserKind::Approximate {
            return Self {
                inv: inverse_or_zero(&n.phi),
                line_search: None,
            };
        }
        let mean =
            n.phi.iter().map(|&v| v.max(0.0) as f64).sum::<f64>() / n.phi.len().max(1) as f64;
        let eps = (GAP_DAMPING * mean) as f32;
        Self {
            inv: n
                .phi
                .iter()
                .map(|&d| if d > 0.0 { 1.0 / (d + eps) } else { 0.0 })
                .collect(),
            line_search: Some(eps as f64),
        }
    }

    pub(crate) fn admm(n: AatNormaliser, gamma: f32) -> Self {
        Self {
            inv: n.phi.iter().map(|&d| 1.0 / (d + gamma)).collect(),
            line_search: (n.kind == NormaliserKind::Approximate).then_some(gamma as f64),
        }
    }

    /// τ = ⟨r, p⟩ / (‖Aᵀ p‖² + ε‖p‖²) when searched (from ⟨r, p⟩ and ‖p‖²,
    /// accumulated while forming p, and the step Aᵀ p), else 1.
    pub(crate) fn tau(&self, r_dot_p: f64, p_sq: f64, step: &[f32]) -> f32 {
        let Some(eps) = self.line_search else {
            return 1.0;
        };
        let den = par_norm_sq(step) + eps * p_sq;
        if den > 0.0 && r_dot_p > 0.0 {
            (r_dot_p / den) as f32
        } else {
            1.0
        }
    }
}

/// Σ (a − b)² with 8 independent f32 lanes, as f64.
#[inline]
pub(crate) fn lanes_dist_sq(a: &[f32], b: &[f32]) -> f64 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            let d = x[i] - y[i];
            acc[i] += d * d;
        }
    }
    let tail: f32 = ra.iter().zip(rb).map(|(x, y)| (x - y) * (x - y)).sum();
    acc.iter().map(|&v| v as f64).sum::<f64>() + tail as f64
}

/// Reports an iteration to the observer and applies the stopping rules
/// (observer first, then `change < tolerance`); `Some` ends the solve.
pub(crate) fn check_stop(
    observer: &mut dyn super::Observer,
    info: &super::IterationInfo,
    tolerance: f64,
) -> Option<super::StopReason> {
    if observer.on_iteration(info) == super::Control::Stop {
        Some(super::StopReason::Observer)
    } else if info.relative_change < tolerance {
        Some(super::StopReason::Converged)
    } else {
        None
    }
}

/// The solution, with the returned cube's own residual ‖y − A x‖/‖y‖ (the
/// per-iteration one is of the point where the data term was linearised);
/// `y_hat` is scratch of the range's length.
pub(crate) fn finish(
    op: &dyn LinearOperator,
    y: &[f32],
    cube: crate::Cube,
    y_hat: &mut [f32],
    iterations: usize,
    stop: super::StopReason,
) -> super::Solution {
    op.apply(cube.as_slice(), y_hat);
    let res_sq: f64 = y
        .iter()
        .zip(y_hat.iter())
        .map(|(a, b)| ((a - b) as f64).powi(2))
        .sum();
    super::Solution {
        cube,
        iterations,
        stop,
        relative_residual: res_sq.sqrt() / norm_sq(y).sqrt().max(f64::MIN_POSITIVE),
    }
}

/// The checks every diag-normalised solver makes, and its normaliser:
/// shapes and finiteness, the iteration count, the strength schedule, and
/// the operator's [`AatNormaliser`], which `solver` needs and `op` must provide.
pub(crate) fn prepare(
    op: &dyn LinearOperator,
    y: &[f32],
    shape: (usize, usize, usize),
    iterations: usize,
    strength: &super::Strength,
    solver: &str,
) -> Result<AatNormaliser> {
    check_problem(op, y, shape)?;
    check_iterations(iterations)?;
    strength.validate()?;
    op.aat_normaliser()
        .ok_or_else(|| CassiError::InvalidParameter {
            name: "operator",
            value: f64::NAN,
            reason: format!(
                "{solver} needs a normaliser of A Aᵀ (diag(A Aᵀ) or a majoriser), which this operator does not provide"
            ),
        })
}
