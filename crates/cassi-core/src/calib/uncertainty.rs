//! Per-parameter standard errors from the score's curvature.

use super::{CalibrationProblem, ProxyParams, Uncertainty};
use crate::optics::DispersionModel;
use crate::params::Mismatch;

/// σ_i = sqrt(2 f₀ / (N · f_ii)) from central second differences f_ii; also
/// returns how many scores it evaluated.
pub(crate) fn curvature_uncertainty(
    problem: &CalibrationProblem<'_>,
    at: &Mismatch,
    f0: f64,
    proxy: &ProxyParams,
) -> (Uncertainty, usize) {
    let n = problem.measurement.as_slice().len() as f64;
    let evaluations = std::cell::Cell::new(0);
    let axis = |h: f64, set: &dyn Fn(&mut Mismatch, f64)| -> Option<f64> {
        evaluations.set(evaluations.get() + 2);
        let (mut p, mut m) = (*at, *at);
        set(&mut p, h);
        set(&mut m, -h);
        let (fp, fm) = (
            problem.score(&p, proxy).ok()?,
            problem.score(&m, proxy).ok()?,
        );
        let c = (fp + fm - 2.0 * f0) / (h * h);
        (c > 0.0).then(|| (2.0 * f0 / (n * c)).sqrt())
    };
    let subpixel = problem.model == DispersionModel::Subpixel;
    let u = Uncertainty {
        dx: axis(0.05, &|m, d| m.dx += d),
        dy: axis(0.05, &|m, d| m.dy += d),
        theta_deg: axis(0.05, &|m, d| m.theta_deg += d),
        a1: if subpixel {
            axis(0.005, &|m, d| m.a1 += d)
        } else {
            None
        },
        alpha_deg: if subpixel {
            axis(0.2, &|m, d| m.alpha_deg += d)
        } else {
            None
        },
    };
    (u, evaluations.get())
}
