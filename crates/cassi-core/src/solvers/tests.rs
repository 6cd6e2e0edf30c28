//! Solver properties that hold whatever the denoiser.

use super::*;
use crate::cube::{Cube, Frame};
use crate::denoise::NoPrior;
use crate::linop::LinearOperator;
use crate::optics::{CassiOperator, Dispersion, DispersionModel};
use crate::rng::Rng;

fn problem(seed: u64) -> (CassiOperator, Vec<f32>, (usize, usize, usize)) {
    let mut rng = Rng::new(seed);
    let (l, h, w) = (6, 12, 10);
    let mask = Frame::from_vec(
        h,
        w,
        (0..h * w)
            .map(|_| (rng.uniform() < 0.5) as u8 as f32)
            .collect(),
    )
    .unwrap();
    let op = CassiOperator::new(
        mask,
        Dispersion::nominal(l, 2.0, DispersionModel::Rounded).unwrap(),
    )
    .unwrap();
    let x: Vec<f32> = (0..l * h * w).map(|_| rng.uniform() as f32).collect();
    let mut y = vec![0.0; op.range_len()];
    op.apply(&x, &mut y);
    (op, y, (l, h, w))
}

fn relative_residual(op: &CassiOperator, x: &Cube, y: &[f32]) -> f64 {
    let mut yh = vec![0.0; op.range_len()];
    op.apply(x.as_slice(), &mut yh);
    let e: f64 = y
        .iter()
        .zip(&yh)
        .map(|(a, b)| ((a - b) as f64).powi(2))
        .sum();
    let n: f64 = y.iter().map(|a| (*a as f64).powi(2)).sum();
    (e / n).sqrt()
}

#[test]
fn one_plain_gap_step_is_an_exact_projection_when_aat_is_diagonal() {
    let (op, y, shape) = problem(1);
    let params = GapParams {
        iterations: 1,
        accelerate: false,
        nonnegative: false,
        ..Default::default()
    };
    let sol = Gap::new(params)
        .solve(&op, &y, shape, &mut NoPrior, &mut Silent)
        .unwrap();
    let r = relative_residual(&op, &sol.cube, &y);
    assert!(r < 1e-6, "residual after one projection: {r}");
}

#[test]
fn accelerated_gap_and_admm_reach_data_consistency() {
    let (op, y, shape) = problem(2);
    let gap = GapParams {
        iterations: 30,
        ..Default::default()
    };
    let sol = Gap::new(gap)
        .solve(&op, &y, shape, &mut NoPrior, &mut Silent)
        .unwrap();
    assert!(relative_residual(&op, &sol.cube, &y) < 1e-3);
    let mut history = History::default();
    let admm = AdmmParams {
        iterations: 60,
        ..Default::default()
    };
    let sol = Admm::new(admm)
        .solve(&op, &y, shape, &mut NoPrior, &mut history)
        .unwrap();
    let r = relative_residual(&op, &sol.cube, &y);
    assert!(r < 0.05, "ADMM residual {r}");
    let first = history.iterations[0].relative_residual;
    assert!(history.iterations.last().unwrap().relative_residual < first / 5.0);
}

#[test]
fn observer_and_tolerance_stop_the_solve() {
    let (op, y, shape) = problem(3);
    let mut stop_at_3 = |info: &IterationInfo| {
        if info.iteration == 3 {
            Control::Stop
        } else {
            Control::Continue
        }
    };
    let sol = Gap::new(GapParams::default())
        .solve(&op, &y, shape, &mut NoPrior, &mut stop_at_3)
        .unwrap();
    assert_eq!((sol.iterations, sol.stop), (3, StopReason::Observer));
    let params = GapParams {
        tolerance: 1e-3,
        ..Default::default()
    };
    let sol = Gap::new(params)
        .solve(&op, &y, shape, &mut NoPrior, &mut Silent)
        .unwrap();
    assert_eq!(sol.stop, StopReason::Converged);
    assert!(sol.iterations < 100);
}

#[test]
fn bad_problems_are_errors() {
    let (op, y, _) = problem(4);
    let mut gap = Gap::new(GapParams::default());
    assert!(
        gap.solve(&op, &y, (6, 12, 11), &mut NoPrior, &mut Silent)
            .is_err()
    );
    assert!(
        gap.solve(&op, &y[1..], (6, 12, 10), &mut NoPrior, &mut Silent)
            .is_err()
    );
    let mut bad = y.clone();
    bad[5] = f32::NAN;
    assert!(
        gap.solve(&op, &bad, (6, 12, 10), &mut NoPrior, &mut Silent)
            .unwrap_err()
            .to_string()
            .contains("index 5")
    );
    let mut zero = Gap::new(GapParams {
        iterations: 0,
        ..Default::default()
    });
    assert!(
        zero.solve(&op, &y, (6, 12, 10), &mut NoPrior, &mut Silent)
            .is_err()
    );
    let mut admm = Admm::new(AdmmParams {
        gamma: 0.0,
        ..Default::default()
    });
    assert!(
        admm.solve(&op, &y, (6, 12, 10), &mut NoPrior, &mut Silent)
            .is_err()
    );
}
