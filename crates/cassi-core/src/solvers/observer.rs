//! What a solver reports each iteration, and how a caller stops it
//! (progress bars, residual histories, time budgets, cancellation).

use std::time::{Duration, Instant};

/// The state after one iteration.
#[derive(Debug, Clone, Copy)]
pub struct IterationInfo {
    /// 1-based iteration number.
    pub iteration: usize,
    pub max_iterations: usize,
    /// ‖y − A v‖ / ‖y‖ at the point v where this iteration linearised the
    /// data term (GAP: the incoming iterate; ADMM: θ + b).
    pub relative_residual: f64,
    /// ‖x_new − x_old‖ / ‖x_old‖.
    pub relative_change: f64,
    /// Time since the solve started.
    pub elapsed: Duration,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    Continue,
    Stop,
}

/// Called once per iteration; return [`Control::Stop`] to end the solve
/// early (the current iterate is returned).
pub trait Observer {
    fn on_iteration(&mut self, info: &IterationInfo) -> Control;
}

/// Observes nothing.
pub struct Silent;

impl Observer for Silent {
    fn on_iteration(&mut self, _: &IterationInfo) -> Control {
        Control::Continue
    }
}

/// Records every iteration.
#[derive(Debug, Default, Clone)]
pub struct History {
    pub iterations: Vec<IterationInfo>,
}

impl Observer for History {
    fn on_iteration(&mut self, info: &IterationInfo) -> Control {
        self.iterations.push(*info);
        Control::Continue
    }
}

/// Stops when a wall-clock budget is spent.
pub struct TimeBudget {
    deadline: Instant,
}

impl TimeBudget {
    pub fn new(budget: Duration) -> Self {
        Self {
            deadline: Instant::now() + budget,
        }
    }
}

impl Observer for TimeBudget {
    fn on_iteration(&mut self, _: &IterationInfo) -> Control {
        if Instant::now() >= self.deadline {
            Control::Stop
        } else {
            Control::Continue
        }
    }
}

/// Any closure `FnMut(&IterationInfo) -> Control` is an observer.
impl<F: FnMut(&IterationInfo) -> Control> Observer for F {
    fn on_iteration(&mut self, info: &IterationInfo) -> Control {
        self(info)
    }
}
