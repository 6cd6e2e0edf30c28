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
