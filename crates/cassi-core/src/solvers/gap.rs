//! Generalized alternating projection (GAP; Liao, Li & Carin 2014) with any
//! denoiser as the prior step, plain or accelerated with Yuan's (2016)
//! accumulated residual.
//!
//! One iteration, with Φ the operator's normaliser of A Aᵀ
//! ([`crate::LinearOperator::aat_normaliser`]):
//! ```text
//! plain:        x ← x + τ Aᵀ((y − A x) / Φ)
//! accelerated:  y₁ ← y₁ + (y − A x);  x ← x + τ Aᵀ((y₁ − A x) / Φ)
//! then          x ← D(max(x, 0), λ_k)   (the clamp when `nonnegative`)
//! ```
//! starting from x = Aᵀ y, y₁ = 0. GAP-TV is this with a TV denoiser.
//!
//! Φ = diag(A Aᵀ) when A Aᵀ is diagonal (CASSI's rounded model: τ = 1 is the
//! exact projection onto {A x = y}); the row sums A Aᵀ 𝟙 ⪰ A Aᵀ when it is
//! not (the subpixel model's split taps: τ = 1, a relaxed projection that
//! never overshoots); τ is line-searched only for an operator that
//! guarantees neither. Why not the line search or diag(A Aᵀ) for split taps:
//! see `DataStep` in `common.rs` (issue #13).

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::common::{DataStep, add_step, check_stop, finish, norm_sq, prepare};
use super::observer::{IterationInfo, Observer};
use super::schedule::Strength;
use super::{Solution, StopReason};
use crate::cube::Cube;
use crate::denoise::Denoiser;
use crate::error::Result;
use crate::linop::LinearOperator;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GapParams {
    /// Maximum number of iterations.
    pub iterations: usize,
    /// Yuan's accumulated-residual acceleration.
    pub accelerate: bool,
    /// Denoiser strength per iteration (the TV weight for GAP-TV).
    pub strength: Strength,
    /// Clamp x at 0 before denoising (scenes are non-negative).
    pub nonnegative: bool,
    /// Stop when the data-consistency step ‖Aᵀ((·)/Φ)‖/‖x‖ falls below this
    /// (0 = run all iterations).
    pub tolerance: f64,
}

impl Default for GapParams {
    fn default() -> Self {
        Self {
            iterations: 100,
            accelerate: true,
            strength: Strength::Constant { value: 0.1 },
            nonnegative: true,
            tolerance: 0.0,
        }
    }
}

/// The GAP solver with its buffers: reusing one `Gap` for several solves of
/// the same size allocates nothing after the first.
#[derive(Default)]
pub struct Gap {
    pub params: GapParams,
    y_hat: Vec<f32>,
    y_acc: Vec<f32>,
    residual: Vec<f32>,
    step: Vec<f32>,
}

impl Gap {
    pub fn new(params: GapParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    /// Reconstructs a cube of `shape` = (bands, rows, cols) from `y`.
    pub fn solve(
        &mut self,
        op: &dyn LinearOperator,
        y: &[f32],
        shape: (usize, usize, usize),
        denoiser: &mut dyn Denoiser,
        observer: &mut dyn Observer,
    ) -> Result<Solution> {
        let p = self.params;
        let data_step = DataStep::gap(prepare(op, y, shape, p.iterations, &p.strength, "GAP")?);
        let inv_phi = &data_step.inv;
        let searched = data_step.line_search.is_some();
        let (m, n) = (op.range_len(), op.domain_len());
        for buf in [&mut self.y_hat, &mut self.y_acc, &mut self.residual] {
            buf.clear();
            buf.resize(m, 0.0);
        }
        self.step.clear();
        self.step.resize(n, 0.0);

        let (l, h, w) = shape;
        let mut x = Cube::zeros(l, h, w);
        op.adjoint(y, x.as_mut_slice());
        let y_norm = norm_sq(y).sqrt().max(f64::MIN_POSITIVE);
        let t0 = Instant::now();
        let mut stop = StopReason::MaxIterations;
        let mut done = 0;
        for it in 0..p.iterations {
            op.apply(x.as_slice(), &mut self.y_hat);
            let (mut res_sq, mut t_dot_p, mut p_sq) = (0.0f64, 0.0f64, 0.0f64);
            for i in 0..m {
                let e = y[i] - self.y_hat[i];
                res_sq += e as f64 * e as f64;
                let target = if p.accelerate {
                    self.y_acc[i] += e;
                    self.y_acc[i] - self.y_hat[i]
                } else {
                    e
                };
                let pi = target * inv_phi[i];
                self.residual[i] = pi;
                if searched {
                    t_dot_p += target as f64 * pi as f64;
                    p_sq += pi as f64 * pi as f64;
                }
            }
            let last_residual = res_sq.sqrt() / y_norm;
            op.adjoint(&self.residual, &mut self.step);
            let tau = data_step.tau(t_dot_p, p_sq, &self.step);
            let (step_sq, x_sq) = add_step(x.as_mut_slice(), &self.step, tau, p.nonnegative);
            denoiser.denoise(&mut x, p.strength.at(it, p.iterations));
            done = it + 1;
            let relative_step = step_sq.sqrt() / x_sq.sqrt().max(f64::MIN_POSITIVE);
            let info = IterationInfo {
                iteration: done,
                max_iterations: p.iterations,
                relative_residual: last_residual,
                relative_change: relative_step,
                elapsed: t0.elapsed(),
            };
            if let Some(reason) = check_stop(observer, &info, p.tolerance) {
                stop = reason;
                break;
            }
        }
        Ok(finish(op, y, x, &mut self.y_hat, done, stop))
    }
}
