//! Iterative reconstruction: GAP and ADMM with any [`crate::Denoiser`] as the
//! prior (plug-and-play), written against [`crate::LinearOperator`] so a new
//! instrument model plugs into every solver.
//!
//! Each solver is a struct of typed parameters (with documented `Default`s)
//! plus its buffers, run with `solve(op, y, shape, denoiser, observer)`. The
//! observer sees every iteration and may stop the solve; the stopping rules
//! (iteration cap, tolerance, observer) are explicit in [`StopReason`].

pub mod admm;
pub mod cgls;
mod common;
pub mod gap;
pub mod observer;
pub mod schedule;

pub use admm::{Admm, AdmmParams};
pub use cgls::{CglsOutcome, CglsParams, CglsScratch, cgls};
pub use gap::{Gap, GapParams};
pub use observer::{Control, History, IterationInfo, Observer, Silent, TimeBudget};
pub use schedule::Strength;

use serde::{Deserialize, Serialize};

/// Why a solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    MaxIterations,
    /// The solver's convergence measure fell below its tolerance.
    Converged,
    /// The observer asked to stop (time budget, cancellation).
    Observer,
}

/// A reconstruction and how it ended.
#[derive(Debug, Clone)]
pub struct Solution {
    pub cube: crate::Cube,
    pub iterations: usize,
    pub stop: StopReason,
    /// ‖y − A x‖ / ‖y‖ of the returned cube.
    pub relative_residual: f64,
}

#[cfg(test)]
mod tests;
