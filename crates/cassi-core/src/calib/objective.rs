//! What the searches minimise: a score over ψ seen through a subset of its
//! parameters. A search moves a vector of the free parameters; every other
//! component of ψ stays at the objective's base. Every evaluation is
//! counted on the stage that owns the objective (`stages.rs`).

use std::cell::Cell;

use crate::params::{Mismatch, Parameter};

/// A count of score (or score-and-gradient) evaluations.
#[derive(Debug, Default)]
pub(crate) struct Evaluations(Cell<usize>);

impl Evaluations {
    pub(crate) fn count(&self) -> usize {
        self.0.get()
    }

    pub(crate) fn add_one(&self) {
        self.0.set(self.0.get() + 1);
    }
}

/// A score and its gradient along the given parameters (same order).
pub(crate) type ScoreAndGradient<'a> = dyn Fn(&Mismatch, &[Parameter]) -> (f64, Vec<f64>) + 'a;

/// How a search coordinate becomes its parameter's value in ψ.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Coordinate {
    /// As it is.
    Free,
    /// Clamped to [lo, hi]: the search may step outside, ψ does not.
    Within(f64, f64),
    /// As |x|: a width the search may carry through 0.
    Magnitude,
}

/// The function an objective evaluates at ψ.
#[derive(Clone, Copy)]
enum Function<'a> {
    Score(&'a dyn Fn(&Mismatch) -> f64),
    ScoreAndGradient(&'a ScoreAndGradient<'a>),
}

/// A score over the parameters `free`, the rest of ψ held at a base.
pub(crate) struct Objective<'a> {
    function: Function<'a>,
    base: Mismatch,
    free: Vec<(Parameter, Coordinate)>,
    evaluations: &'a Evaluations,
}

impl<'a> Objective<'a> {
    /// `score` over `free` around `base`, each evaluation counted on `evaluations`.
    pub(crate) fn new(
        score: &'a dyn Fn(&Mismatch) -> f64,
        base: Mismatch,
        free: &[Parameter],
        evaluations: &'a Evaluations,
    ) -> Self {
        Self::with(Function::Score(score), base, free, evaluations)
    }

    /// A differentiable score (`score_and_gradient(ψ, parameters)`), for the
    /// gradient searches.
    pub(crate) fn differentiable(
        score_and_gradient: &'a ScoreAndGradient<'a>,
        base: Mismatch,
        free: &[Parameter],
        evaluations: &'a Evaluations,
    ) -> Self {
        Self::with(
            Function::ScoreAndGradient(score_and_gradient),
            base,
            free,
            evaluations,
        )
    }

    fn with(
        function: Function<'a>,
        base: Mismatch,
        free: &[Parameter],
        evaluations: &'a Evaluations,
    ) -> Self {
        Self {
            function,
            base,
            free: free.iter().map(|&p| (p, Coordinate::Free)).collect(),
            evaluations,
        }
    }

    /// Holds `p` (if free) inside [lo, hi] in every ψ this objective makes.
    pub(crate) fn within(mut self, p: Parameter, lo: f64, hi: f64) -> Self {
        self.set_coordinate(p, Coordinate::Within(lo, hi));
        self
    }

    /// Takes `p` (if free) as the magnitude of its coordinate.
    pub(crate) fn magnitude(mut self, p: Parameter) -> Self {
        self.set_coordinate(p, Coordinate::Magnitude);
        self
    }

    fn set_coordinate(&mut self, p: Parameter, c: Coordinate) {
        for (q, coordinate) in &mut self.free {
            if *q == p {
                *coordinate = c;
            }
        }
    }

    /// The free parameters, in the search vector's order.
    pub(crate) fn parameters(&self) -> Vec<Parameter> {
        self.free.iter().map(|&(p, _)| p).collect()
    }

    /// The base's free parameters: the search's starting vector.
    pub(crate) fn start(&self) -> Vec<f64> {
        self.free.iter().map(|&(p, _)| p.get(&self.base)).collect()
    }

    /// ψ for the search vector `v`.
    pub(crate) fn psi(&self, v: &[f64]) -> Mismatch {
        let mut m = self.base;
        for (&(p, coordinate), &x) in self.free.iter().zip(v) {
            let x = match coordinate {
                Coordinate::Free => x,
                Coordinate::Within(lo, hi) => x.clamp(lo, hi),
                Coordinate::Magnitude => x.abs(),
            };
            p.set(&mut m, x);
        }
        m
    }

    /// Clamps the coordinates held within bounds, in place (a projected
    /// gradient step).
    pub(crate) fn project(&self, v: &mut [f64]) {
        for (&(_, coordinate), x) in self.free.iter().zip(v.iter_mut()) {
            if let Coordinate::Within(lo, hi) = coordinate {
                *x = x.clamp(lo, hi);
            }
        }
    }

    /// The score at `v` (one evaluation).
    pub(crate) fn value(&self, v: &[f64]) -> f64 {
        self.evaluations.add_one();
        let psi = self.psi(v);
        match self.function {
            Function::Score(score) => score(&psi),
            Function::ScoreAndGradient(f) => f(&psi, &[]).0,
        }
    }

    /// The score at `v` and its gradient along the free parameters (one
    /// evaluation). Only a [`differentiable`](Self::differentiable)
    /// objective has a gradient.
    pub(crate) fn value_and_gradient(&self, v: &[f64]) -> (f64, Vec<f64>) {
        let Function::ScoreAndGradient(f) = self.function else {
            panic!("a gradient search was given an objective without a gradient");
        };
        self.evaluations.add_one();
        f(&self.psi(v), &self.parameters())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_search_vector_moves_only_the_free_parameters_with_their_clamps() {
        let base = Mismatch::paper();
        let n = Evaluations::default();
        let score = |m: &Mismatch| m.dx + m.a1 + m.blur_sigma_px;
        let objective = Objective::new(
            &score,
            base,
            &[Parameter::Dx, Parameter::A1, Parameter::BlurSigmaPx],
            &n,
        )
        .within(Parameter::A1, 2.0, 2.05)
        .magnitude(Parameter::BlurSigmaPx)
        // not free: no effect
        .within(Parameter::Dy, 0.0, 0.0);
        assert_eq!(objective.start(), vec![1.5, 2.04, 0.0]);
        let m = objective.psi(&[0.5, 2.3, -0.25]);
        assert_eq!(
            m,
            Mismatch {
                dx: 0.5,
                a1: 2.05,
                blur_sigma_px: 0.25,
                ..base
            }
        );
        assert_eq!(objective.value(&[0.5, 1.0, -0.25]), 0.5 + 2.0 + 0.25);
        assert_eq!(objective.value(&[0.0, 2.0, 0.0]), 2.0);
        assert_eq!(n.count(), 2);
        let mut v = vec![9.0, 9.0, -9.0];
        objective.project(&mut v);
        assert_eq!(v, vec![9.0, 2.05, -9.0], "only bounded coordinates move");
    }

    #[test]
    fn a_differentiable_objective_asks_for_the_gradient_along_its_free_parameters() {
        let n = Evaluations::default();
        let f = |m: &Mismatch, ps: &[Parameter]| (m.dy, ps.iter().map(|p| p.get(m)).collect());
        let objective = Objective::differentiable(
            &f,
            Mismatch::nominal(2.0),
            &[Parameter::ThetaDeg, Parameter::Dy],
            &n,
        );
        assert_eq!(
            objective.value_and_gradient(&[0.25, -1.0]),
            (-1.0, vec![0.25, -1.0])
        );
        assert_eq!(objective.value(&[0.0, 3.0]), 3.0);
        assert_eq!(n.count(), 2);
    }
}
