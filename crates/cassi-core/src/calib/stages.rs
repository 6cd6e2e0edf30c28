//! The stage runner the presets are written over: it times each stage,
//! counts the evaluations of the objectives the stage made, records the
//! stage's best ψ and score as a [`StageReport`] and shows it to the
//! caller's `on_stage` as it finishes. Reports are built here only.

use std::time::Instant;

use super::objective::{Evaluations, Objective, ScoreAndGradient};
use super::{PassedOver, StageReport};
use crate::params::{Mismatch, Parameter};

/// A ψ and its score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Scored {
    pub(crate) parameters: Mismatch,
    pub(crate) score: f64,
}

impl Scored {
    /// `parameters` where nothing scored below +∞ (a search that kept its start).
    pub(crate) fn infinite(parameters: Mismatch) -> Self {
        Self {
            parameters,
            score: f64::INFINITY,
        }
    }
}

/// The first of the lowest-scoring results; `None` if none scores below +∞
/// (a NaN never wins).
pub(crate) fn lowest(scored: &[Scored]) -> Option<Scored> {
    let mut best: Option<Scored> = None;
    for s in scored {
        if s.score < best.map_or(f64::INFINITY, |b| b.score) {
            best = Some(*s);
        }
    }
    best
}

/// One stage under way: its clock and its evaluation count.
#[must_use = "a stage is reported by `StageRunner::finish`"]
pub(crate) struct Stage {
    started: Instant,
    evaluations: Evaluations,
}

impl Stage {
    /// `score` over `free` around `base`, counted on this stage.
    pub(crate) fn objective<'a>(
        &'a self,
        score: &'a dyn Fn(&Mismatch) -> f64,
        base: Mismatch,
        free: &[Parameter],
    ) -> Objective<'a> {
        Objective::new(score, base, free, &self.evaluations)
    }

    /// A differentiable score over `free` around `base`, counted on this stage.
    pub(crate) fn differentiable<'a>(
        &'a self,
        score_and_gradient: &'a ScoreAndGradient<'a>,
        base: Mismatch,
        free: &[Parameter],
    ) -> Objective<'a> {
        Objective::differentiable(score_and_gradient, base, free, &self.evaluations)
    }

    /// Counts `n` evaluations a search made outside an [`Objective`].
    pub(crate) fn count(&self, n: usize) {
        for _ in 0..n {
            self.evaluations.add_one();
        }
    }

    /// `score` at ψ whole (one evaluation), for searches that move several
    /// parameters together.
    pub(crate) fn score(&self, score: &dyn Fn(&Mismatch) -> f64, psi: &Mismatch) -> f64 {
        self.objective(score, *psi, &[]).value(&[])
    }
}

/// Runs a preset's stages and keeps their reports.
pub(crate) struct StageRunner<'a> {
    started: Instant,
    reports: Vec<StageReport>,
    on_stage: &'a mut dyn FnMut(&StageReport),
    /// Put before every stage name (a stage run again inside another).
    prefix: &'static str,
}

impl<'a> StageRunner<'a> {
    /// A calibration starting now; `on_stage` sees each stage as it finishes.
    pub(crate) fn new(on_stage: &'a mut dyn FnMut(&StageReport)) -> Self {
        Self {
            started: Instant::now(),
            reports: Vec::new(),
            on_stage,
            prefix: "",
        }
    }

    /// Runs `stages` with `prefix` before each of their names: stages run
    /// again inside another (a restart's fits), reported in order with the
    /// rest.
    pub(crate) fn prefixed<R>(
        &mut self,
        prefix: &'static str,
        stages: impl FnOnce(&mut Self) -> R,
    ) -> R {
        let outer = std::mem::replace(&mut self.prefix, prefix);
        let out = stages(self);
        self.prefix = outer;
        out
    }

    /// Starts a stage's clock and count.
    pub(crate) fn start(&self) -> Stage {
        Stage {
            started: Instant::now(),
            evaluations: Evaluations::default(),
        }
    }

    /// Ends `stage` as `name` with its best ψ and score; returns that ψ.
    pub(crate) fn finish(
        &mut self,
        stage: Stage,
        name: impl Into<String>,
        best: Scored,
    ) -> Mismatch {
        self.report(stage, name.into(), best, None)
    }

    /// [`Self::finish`] for a stage that chose `best` over `passed_over`.
    pub(crate) fn finish_choosing(
        &mut self,
        stage: Stage,
        name: impl Into<String>,
        best: Scored,
        passed_over: PassedOver,
    ) -> Mismatch {
        self.report(stage, name.into(), best, Some(passed_over))
    }

    fn report(
        &mut self,
        stage: Stage,
        name: String,
        best: Scored,
        passed_over: Option<PassedOver>,
    ) -> Mismatch {
        let name = if self.prefix.is_empty() {
            name
        } else {
            format!("{}{name}", self.prefix)
        };
        let report = StageReport {
            name,
            evaluations: stage.evaluations.count(),
            seconds: stage.started.elapsed().as_secs_f64(),
            parameters: best.parameters,
            score: best.score,
            passed_over,
        };
        (self.on_stage)(&report);
        self.reports.push(report);
        best.parameters
    }

    /// The evaluations of every finished stage.
    pub(crate) fn evaluations(&self) -> usize {
        self.reports.iter().map(|s| s.evaluations).sum()
    }

    /// Seconds since the runner was made.
    pub(crate) fn seconds(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// The reports, in the order the stages finished.
    pub(crate) fn into_reports(self) -> Vec<StageReport> {
        self.reports
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stage_reports_the_evaluations_of_its_objectives_and_its_best() {
        let mut seen = Vec::new();
        let mut on_stage = |r: &StageReport| seen.push(r.name.clone());
        let mut run = StageRunner::new(&mut on_stage);
        let score = |m: &Mismatch| (m.dx - 1.0).powi(2);
        let stage = run.start();
        let a = stage.objective(&score, Mismatch::nominal(2.0), &[Parameter::Dx]);
        let b = stage.objective(&score, Mismatch::nominal(2.0), &[Parameter::Dx]);
        a.value(&[0.0]);
        b.value(&[1.0]);
        let s = stage.score(&score, &Mismatch::nominal(2.0));
        let best = Scored {
            parameters: b.psi(&[1.0]),
            score: 0.0,
        };
        assert_eq!(s, 1.0);
        assert_eq!(run.finish(stage, "one", best), best.parameters);
        let stage = run.start();
        stage.score(&score, &Mismatch::nominal(2.0));
        run.finish(stage, "two", best);
        assert_eq!(run.evaluations(), 4);
        let reports = run.into_reports();
        assert_eq!(
            reports.iter().map(|r| r.evaluations).collect::<Vec<_>>(),
            vec![3, 1]
        );
        assert_eq!(reports[0].parameters.dx, 1.0);
        assert_eq!(seen, vec!["one", "two"]);
    }

    #[test]
    fn prefixed_stages_carry_the_prefix_and_the_runner_drops_it_after() {
        let mut seen = Vec::new();
        let mut on_stage = |r: &StageReport| seen.push(r.name.clone());
        let mut run = StageRunner::new(&mut on_stage);
        let best = Scored::infinite(Mismatch::nominal(2.0));
        run.prefixed("again: ", |run| {
            let stage = run.start();
            run.finish(stage, "fit", best);
        });
        let stage = run.start();
        run.finish(stage, "choice", best);
        assert_eq!(seen, vec!["again: fit", "choice"]);
    }
}
