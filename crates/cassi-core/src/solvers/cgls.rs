//! CGLS: conjugate gradients on the normal equations of min_z ‖b − K z‖²
//! without forming Kᵀ K (Hestenes–Stiefel; Björck, *Numerical Methods for
//! Least Squares Problems*, §7.4). For any linear operator K; the
//! calibration's scene fit solves its coarse scene with it for every
//! candidate instrument, warm-started from the last solution.
//!
//! One iteration, with s = Kᵀ r the normal-equation residual:
//! ```text
//! q ← K p;  α ← ‖s‖² / ‖q‖²;  z ← z + α p;  r ← r − α q
//! s ← Kᵀ r;  β ← ‖s‖² / ‖s_old‖²;  p ← s + β p
//! ```
//! In exact arithmetic ‖r‖ decreases monotonically, so a warm start is never
//! made worse. The buffers live in [`CglsScratch`]: nothing is allocated in
//! the loop.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::StopReason;
use super::observer::{Control, IterationInfo, Observer};
use crate::linop::LinearOperator;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CglsParams {
    /// Maximum number of iterations.
    pub iterations: usize,
    /// Stop when an iteration lowers ‖r‖² by less than this fraction of it.
    pub tolerance: f64,
}

impl Default for CglsParams {
    fn default() -> Self {
        Self {
            iterations: 100,
            tolerance: 1e-6,
        }
    }
}

/// The iteration's vectors: `r`, `q` in K's range, `s`, `p` in its domain.
#[derive(Debug, Default)]
pub struct CglsScratch {
    r: Vec<f32>,
    q: Vec<f32>,
    s: Vec<f32>,
    p: Vec<f32>,
}

impl CglsScratch {
    /// b − K z after the last solve.
    pub fn residual(&self) -> &[f32] {
        &self.r
    }
}

/// How a solve ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CglsOutcome {
    /// ‖b − K z‖² at the returned z.
    pub residual_sq: f64,
    pub iterations: usize,
    pub stop: StopReason,
}

fn norm_sq(v: &[f32]) -> f64 {
    v.iter().map(|&x| x as f64 * x as f64).sum()
}

/// Minimises ‖b − K z‖² from the given `z` (a warm start; zeros for a cold
/// one), in place. `observer` sees ‖r‖ / ‖b‖ each iteration and may stop it.
pub fn cgls(
    op: &dyn LinearOperator,
    b: &[f32],
    z: &mut [f32],
    params: &CglsParams,
    scratch: &mut CglsScratch,
    observer: &mut dyn Observer,
) -> CglsOutcome {
    let (m, n) = (op.range_len(), op.domain_len());
    assert_eq!(b.len(), m, "cgls: b has {} values, K's range {m}", b.len());
    assert_eq!(z.len(), n, "cgls: z has {} values, K's domain {n}", z.len());
    let CglsScratch { r, q, s, p } = scratch;
    r.resize(m, 0.0);
    q.resize(m, 0.0);
    s.resize(n, 0.0);
    p.resize(n, 0.0);
    op.apply(z, q);
    r.iter_mut()
        .zip(b.iter().zip(q.iter()))
        .for_each(|(r, (&b, &q))| *r = b - q);
    op.adjoint(r, s);
    p.copy_from_slice(s);
    let mut gamma = norm_sq(s);
    let mut rr = norm_sq(r);
    let bb = norm_sq(b).max(f64::MIN_POSITIVE);
    let start = Instant::now();
    let mut outcome = CglsOutcome {
        residual_sq: rr,
        iterations: 0,
        stop: StopReason::MaxIterations,
    };
    for it in 1..=params.iterations {
        if gamma <= 0.0 {
            outcome.stop = StopReason::Converged;
            break;
        }
        op.apply(p, q);
        let qq = norm_sq(q);
        if qq <= 0.0 {
            outcome.stop = StopReason::Converged;
            break;
        }
        let alpha = (gamma / qq) as f32;
        let step = alpha as f64 * norm_sq(p).sqrt();
        z.iter_mut()
            .zip(p.iter())
            .for_each(|(z, &p)| *z += alpha * p);
        r.iter_mut()
            .zip(q.iter())
            .for_each(|(r, &q)| *r -= alpha * q);
        let rr_new = norm_sq(r);
        op.adjoint(r, s);
        let gamma_new = norm_sq(s);
        let beta = (gamma_new / gamma) as f32;
        gamma = gamma_new;
        p.iter_mut()
            .zip(s.iter())
            .for_each(|(p, &s)| *p = s + beta * *p);
        let decrease = (rr - rr_new) / rr.max(f64::MIN_POSITIVE);
        let change = step / norm_sq(z).sqrt().max(f64::MIN_POSITIVE);
        rr = rr_new;
        outcome.residual_sq = rr;
        outcome.iterations = it;
        let info = IterationInfo {
            iteration: it,
            max_iterations: params.iterations,
            relative_residual: (rr / bb).sqrt(),
            relative_change: change,
            elapsed: start.elapsed(),
        };
        if observer.on_iteration(&info) == Control::Stop {
            outcome.stop = StopReason::Observer;
            break;
        }
        if decrease < params.tolerance {
            outcome.stop = StopReason::Converged;
            break;
        }
    }
    outcome
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::solvers::Silent;

    /// A dense m × n matrix as an operator.
    struct Dense {
        m: usize,
        n: usize,
        a: Vec<f32>,
    }

    impl LinearOperator for Dense {
        fn domain_len(&self) -> usize {
            self.n
        }
        fn range_len(&self) -> usize {
            self.m
        }
        fn apply(&self, x: &[f32], y: &mut [f32]) {
            for (i, yi) in y.iter_mut().enumerate() {
                *yi = (0..self.n).map(|j| self.a[i * self.n + j] * x[j]).sum();
            }
        }
        fn adjoint(&self, y: &[f32], x: &mut [f32]) {
            for (j, xj) in x.iter_mut().enumerate() {
                *xj = (0..self.m).map(|i| self.a[i * self.n + j] * y[i]).sum();
            }
        }
    }

    /// On an overdetermined system CGLS reaches the least-squares solution:
    /// its residual is orthogonal to K's columns (Kᵀ r ≈ 0), it matches the
    /// solution of the normal equations, and a warm start at the answer
    /// stays there.
    #[test]
    fn reaches_the_least_squares_solution() {
        let (m, n) = (40, 6);
        let mut rng = Rng::new(3);
        let a: Vec<f32> = (0..m * n)
            .map(|_| rng.uniform_in(-1.0, 1.0) as f32)
            .collect();
        let op = Dense { m, n, a };
        let b: Vec<f32> = (0..m).map(|_| rng.uniform_in(-1.0, 1.0) as f32).collect();
        let mut z = vec![0.0f32; n];
        let mut scratch = CglsScratch::default();
        let params = CglsParams {
            iterations: 50,
            tolerance: 0.0,
        };
        let out = cgls(&op, &b, &mut z, &params, &mut scratch, &mut Silent);
        let mut kt_r = vec![0.0f32; n];
        op.adjoint(scratch.residual(), &mut kt_r);
        let scale = norm_sq(&b).sqrt();
        assert!(norm_sq(&kt_r).sqrt() < 1e-4 * scale, "Kᵀr = {kt_r:?}");
        // the normal equations solved directly (Gaussian elimination, f64)
        let mut g = vec![0.0f64; n * (n + 1)];
        for i in 0..n {
            for j in 0..n {
                g[i * (n + 1) + j] = (0..m)
                    .map(|k| op.a[k * n + i] as f64 * op.a[k * n + j] as f64)
                    .sum();
            }
            g[i * (n + 1) + n] = (0..m).map(|k| op.a[k * n + i] as f64 * b[k] as f64).sum();
        }
        for c in 0..n {
            for r in c + 1..n {
                let f = g[r * (n + 1) + c] / g[c * (n + 1) + c];
                for k in c..=n {
                    g[r * (n + 1) + k] -= f * g[c * (n + 1) + k];
                }
            }
        }
        let mut x = vec![0.0f64; n];
        for r in (0..n).rev() {
            let s: f64 = (r + 1..n).map(|k| g[r * (n + 1) + k] * x[k]).sum();
            x[r] = (g[r * (n + 1) + n] - s) / g[r * (n + 1) + r];
        }
        for (zi, xi) in z.iter().zip(&x) {
            assert!((*zi as f64 - xi).abs() < 1e-4, "{z:?} vs {x:?}");
        }
        assert!((out.residual_sq - norm_sq(scratch.residual())).abs() < 1e-6);
        let before = z.clone();
        let again = cgls(&op, &b, &mut z, &params, &mut scratch, &mut Silent);
        assert!(again.residual_sq <= out.residual_sq * (1.0 + 1e-5));
        for (a, b) in z.iter().zip(&before) {
            assert!((a - b).abs() < 1e-4);
        }
    }
}
