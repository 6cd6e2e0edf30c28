//! Per-parameter standard errors from the score's curvature.

use super::{CalibrationProblem, ProxyParams, Uncertainty};
use crate::optics::DispersionModel;
use crate::params::{Mismatch, Parameter};

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
    let u = Uncertainty(
        Parameter::ALL
            .iter()
            .map(|&p| {
                // rounded dispersion is piecewise constant in a1 and α: no curvature
                let step = match p {
                    Parameter::Dx | Parameter::Dy | Parameter::ThetaDeg => Some(0.05),
                    Parameter::A1 => subpixel.then_some(0.005),
                    Parameter::AlphaDeg => subpixel.then_some(0.2),
                    Parameter::BlurSigmaPx => None,
                };
                let sigma = step.and_then(|h| axis(h, &|m, d| p.set(m, p.get(m) + d)));
                (p, sigma)
            })
            .collect(),
    );
    (u, evaluations.get())
}
