//! ADMM with any denoiser as the prior step (plug-and-play ADMM; Yuan et al.
//! 2020), with the CASSI-friendly closed-form x-update.
//!
//! One iteration, with Φ the operator's normaliser of A Aᵀ
//! ([`crate::LinearOperator::aat_normaliser`]) and v = θ + b:
//! ```text
//! x ← v + τ Aᵀ((y − A v) / (Φ + γ))    (data consistency, exact for A Aᵀ diagonal)
//! θ ← D(max(x − b, 0), λ_k)            (prior)
//! b ← b − (x − θ)                      (dual update)
//! ```
//! starting from θ = Aᵀ y, b = 0; the answer is θ. ADMM-TV is this with a TV
//! denoiser. Φ = diag(A Aᵀ) (exact) or a majoriser A Aᵀ 𝟙 ⪰ A Aᵀ when
//! dispersion taps split between pixels, τ = 1; τ is line-searched only for
//! an operator that guarantees neither (see `DataStep` in `common.rs`).

use std::time::Instant;

use serde::{Deserialize, Serialize};

use rayon::prelude::*;

use super::common::{
    CHUNK, DataStep, check_stop, finish, lanes_dist_sq, lanes_dot, norm_sq, prepare,
};
use super::observer::{IterationInfo, Observer};
use super::schedule::Strength;
use super::{Solution, StopReason};
use crate::cube::Cube;
use crate::denoise::Denoiser;
use crate::error::{CassiError, Result};
use crate::linop::LinearOperator;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AdmmParams {
    pub iterations: usize,
    /// Penalty γ added to Φ in the x-update (> 0).
    pub gamma: f32,
    pub strength: Strength,
    /// Clamp at 0 before denoising.
    pub nonnegative: bool,
    /// Stop when the primal residual ‖x − θ‖/‖x‖ falls below this (0 = never);
    /// it is also what [`IterationInfo::relative_change`] reports.
    pub tolerance: f64,
}

impl Default for AdmmParams {
    fn default() -> Self {
        Self {
            iterations: 100,
            gamma: 0.01,
            strength: Strength::Constant { value: 0.1 },
            nonnegative: true,
            tolerance: 0.0,
        }
    }
}

/// The ADMM solver with its buffers.
#[derive(Default)]
pub struct Admm {
    pub params: AdmmParams,
    y_hat: Vec<f32>,
    residual: Vec<f32>,
    x: Vec<f32>,
    dual: Vec<f32>,
}

impl Admm {
    pub fn new(params: AdmmParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    pub fn solve(
        &mut self,
        op: &dyn LinearOperator,
        y: &[f32],
        shape: (usize, usize, usize),
        denoiser: &mut dyn Denoiser,
        observer: &mut dyn Observer,
    ) -> Result<Solution> {
        let p = self.params;
        if !(p.gamma.is_finite() && p.gamma > 0.0) {
            return Err(CassiError::InvalidParameter {
                name: "gamma",
                value: p.gamma as f64,
                reason: "the ADMM penalty must be a positive number".into(),
            });
        }
        let data_step = DataStep::admm(
            prepare(op, y, shape, p.iterations, &p.strength, "ADMM")?,
            p.gamma,
        );
        let inv = &data_step.inv;
        let searched = data_step.line_search.is_some();
        let (m, n) = (op.range_len(), op.domain_len());
        self.y_hat.clear();
        self.y_hat.resize(m, 0.0);
        self.residual.clear();
        self.residual.resize(m, 0.0);
        self.x.clear();
        self.x.resize(n, 0.0);
        self.dual.clear();
        self.dual.resize(n, 0.0);

        let (l, h, w) = shape;
        let mut theta = Cube::zeros(l, h, w);
        op.adjoint(y, theta.as_mut_slice());
        let y_norm = norm_sq(y).sqrt().max(f64::MIN_POSITIVE);
        let t0 = Instant::now();
        let mut stop = StopReason::MaxIterations;
        let mut done = 0;
        for it in 0..p.iterations {
            // v = θ + b, kept in `x` until the update below
            self.x
                .par_chunks_mut(CHUNK)
                .zip(theta.as_slice().par_chunks(CHUNK))
                .zip(self.dual.par_chunks(CHUNK))
                .for_each(|((v, t), b)| {
                    v.iter_mut()
                        .zip(t)
                        .zip(b)
                        .for_each(|((v, &t), &b)| *v = t + b)
                });
            op.apply(&self.x, &mut self.y_hat);
            let (mut res_sq, mut r_dot_p, mut p_sq) = (0.0f64, 0.0f64, 0.0f64);
            for i in 0..m {
                let e = y[i] - self.y_hat[i];
                res_sq += e as f64 * e as f64;
                let pi = e * inv[i];
                self.residual[i] = pi;
                if searched {
                    r_dot_p += e as f64 * pi as f64;
                    p_sq += pi as f64 * pi as f64;
                }
            }
            let last_residual = res_sq.sqrt() / y_norm;
            // x = v + τ Aᵀ p (the step lands in θ's storage first: θ_old = v − b)
            op.adjoint(&self.residual, theta.as_mut_slice());
            let tau = data_step.tau(r_dot_p, p_sq, theta.as_slice());
            let nonnegative = p.nonnegative;
            theta
                .as_mut_slice()
                .par_chunks_mut(CHUNK)
                .zip(self.x.par_chunks_mut(CHUNK))
                .zip(self.dual.par_chunks(CHUNK))
                .for_each(|((t, x), b)| {
                    for ((t, xv), &b) in t.iter_mut().zip(x.iter_mut()).zip(b) {
                        *xv += tau * *t;
                        let input = *xv - b;
                        *t = if nonnegative { input.max(0.0) } else { input };
                    }
                });
            denoiser.denoise(&mut theta, p.strength.at(it, p.iterations));
            // b ← b − (x − θ), and the primal residual ‖x − θ‖ / ‖x‖
            let sums: Vec<(f64, f64)> = self
                .dual
                .par_chunks_mut(CHUNK)
                .zip(self.x.par_chunks(CHUNK))
                .zip(theta.as_slice().par_chunks(CHUNK))
                .map(|((d, x), t)| {
                    for ((d, &xv), &t) in d.iter_mut().zip(x).zip(t) {
                        *d -= xv - t;
                    }
                    (lanes_dist_sq(x, t), lanes_dot(x, x))
                })
                .collect();
            let (gap_sq, x_sq) = sums
                .iter()
                .fold((0.0, 0.0), |(a, b), &(g, x)| (a + g, b + x));
            done = it + 1;
            let relative_change = gap_sq.sqrt() / x_sq.sqrt().max(f64::MIN_POSITIVE);
            let info = IterationInfo {
                iteration: done,
                max_iterations: p.iterations,
                relative_residual: last_residual,
                relative_change,
                elapsed: t0.elapsed(),
            };
            if let Some(reason) = check_stop(observer, &info, p.tolerance) {
                stop = reason;
                break;
            }
        }
        Ok(finish(op, y, theta, &mut self.y_hat, done, stop))
    }
}
