//! Pieces shared by the solvers: problem checks and the fused vector passes.

use crate::error::{CassiError, Result, shape_error};
use crate::linop::LinearOperator;

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

/// x ← max(x + step, 0) (or without the clamp), in parallel chunks;
/// returns (‖step‖², ‖x_new‖²).
pub(crate) fn add_step(x: &mut [f32], step: &[f32], nonnegative: bool) -> (f64, f64) {
    use rayon::prelude::*;
    let sums: Vec<(f64, f64)> = x
        .par_chunks_mut(CHUNK)
        .zip(step.par_chunks(CHUNK))
        .map(|(xc, sc)| {
            for (xv, &s) in xc.iter_mut().zip(sc) {
                let v = *xv + s;
                *xv = if nonnegative { v.max(0.0) } else { v };
            }
            (lanes_dot(sc, sc), lanes_dot(xc, xc))
        })
        .collect();
    sums.iter()
        .fold((0.0, 0.0), |(a, b), &(s, x)| (a + s, b + x))
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
/// diag(A Aᵀ), which `solver` needs and `op` must provide.
pub(crate) fn prepare(
    op: &dyn LinearOperator,
    y: &[f32],
    shape: (usize, usize, usize),
    iterations: usize,
    strength: &super::Strength,
    solver: &str,
) -> Result<Vec<f32>> {
    check_problem(op, y, shape)?;
    check_iterations(iterations)?;
    strength.validate()?;
    op.diag_aat().ok_or_else(|| CassiError::InvalidParameter {
        name: "operator",
        value: f64::NAN,
        reason: format!("{solver} needs diag(A Aᵀ), which this operator does not provide"),
    })
}
