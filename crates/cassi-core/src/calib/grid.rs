//! Exhaustive searches: an objective scored at every point of a list or of
//! a Cartesian grid, in order.

use super::objective::Objective;
use super::stages::Scored;

/// `n` evenly spaced values over [lo, hi] (just `lo` when n = 1).
pub(crate) fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            if n == 1 {
                lo
            } else {
                lo + (hi - lo) * i as f64 / (n - 1) as f64
            }
        })
        .collect()
}

/// Every point of the grid `axes[0] × axes[1] × …`, the last axis fastest.
pub(crate) fn product(axes: &[Vec<f64>]) -> Vec<Vec<f64>> {
    axes.iter().fold(vec![Vec::new()], |points, axis| {
        points
            .iter()
            .flat_map(|p| {
                axis.iter().map(move |&x| {
                    let mut q = p.clone();
                    q.push(x);
                    q
                })
            })
            .collect()
    })
}

/// `objective` at every point, in order.
pub(crate) fn scan(objective: &Objective, points: &[Vec<f64>]) -> Vec<Scored> {
    points
        .iter()
        .map(|v| Scored {
            score: objective.value(v),
            parameters: objective.psi(v),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::stages::lowest;
    use crate::params::{Mismatch, Parameter};

    #[test]
    fn the_grid_runs_the_last_axis_fastest_and_the_first_lowest_wins() {
        assert_eq!(linspace(-1.0, 1.0, 3), vec![-1.0, 0.0, 1.0]);
        assert_eq!(linspace(0.5, 1.0, 1), vec![0.5]);
        let points = product(&[vec![0.0, 1.0], vec![10.0, 20.0, 30.0]]);
        assert_eq!(points.len(), 6);
        assert_eq!(points[1], vec![0.0, 20.0]);
        assert_eq!(points[3], vec![1.0, 10.0]);
        let n = crate::calib::objective::Evaluations::default();
        // |dy − 20| ties at (0, 20) and (1, 20): the first is kept
        let score = |m: &Mismatch| (m.dy - 20.0).abs();
        let objective = Objective::new(
            &score,
            Mismatch::nominal(2.0),
            &[Parameter::Dx, Parameter::Dy],
            &n,
        );
        let scored = scan(&objective, &points);
        assert_eq!(n.count(), 6);
        let best = lowest(&scored).unwrap();
        assert_eq!((best.parameters.dx, best.parameters.dy), (0.0, 20.0));
        let never = |_: &Mismatch| f64::INFINITY;
        let objective = Objective::new(&never, Mismatch::nominal(2.0), &[Parameter::Dx], &n);
        assert!(lowest(&scan(&objective, &[vec![0.0]])).is_none());
    }
}
