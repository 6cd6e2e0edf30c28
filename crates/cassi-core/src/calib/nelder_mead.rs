//! A small Nelder–Mead simplex minimiser (standard coefficients), enough for
//! the handful of calibration parameters; counts its evaluations.

use super::objective::Objective;
use super::stages::Scored;

/// [`nelder_mead`] over `objective`'s free parameters from its base: the
/// best ψ found and its score.
pub(crate) fn minimise(
    objective: &Objective,
    steps: &[f64],
    max_evals: usize,
    x_tol: &[f64],
    f_tol: f64,
) -> Scored {
    let (v, score, _) = nelder_mead(
        |v| objective.value(v),
        &objective.start(),
        steps,
        max_evals,
        x_tol,
        f_tol,
    );
    Scored {
        parameters: objective.psi(&v),
        score,
    }
}

/// Minimises `f` from `x0` with initial steps `steps` per coordinate; stops
/// after `max_evals` evaluations or when the simplex's values span less
/// than `f_tol` (relative) and its extent less than `x_tol` in every
/// coordinate. Returns (best x, best f, evaluations).
pub fn nelder_mead(
    mut f: impl FnMut(&[f64]) -> f64,
    x0: &[f64],
    steps: &[f64],
    max_evals: usize,
    x_tol: &[f64],
    f_tol: f64,
) -> (Vec<f64>, f64, usize) {
    let n = x0.len();
    let mut simplex: Vec<Vec<f64>> = vec![x0.to_vec()];
    for i in 0..n {
        let mut p = x0.to_vec();
        p[i] += steps[i];
        simplex.push(p);
    }
    let mut values: Vec<f64> = simplex.iter().map(|p| f(p)).collect();
    let mut evals = n + 1;
    while evals < max_evals {
        let mut order: Vec<usize> = (0..=n).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        simplex = order.iter().map(|&i| simplex[i].clone()).collect();
        values = order.iter().map(|&i| values[i]).collect();
        let spread_f = (values[n] - values[0]).abs() / values[0].abs().max(f64::MIN_POSITIVE);
        let small = (0..n).all(|j| {
            simplex
                .iter()
                .map(|p| (p[j] - simplex[0][j]).abs())
                .fold(0.0, f64::max)
                < x_tol[j]
        });
        if spread_f < f_tol && small {
            break;
        }
        let centroid: Vec<f64> = (0..n)
            .map(|j| simplex[..n].iter().map(|p| p[j]).sum::<f64>() / n as f64)
            .collect();
        let along = |t: f64| -> Vec<f64> {
            (0..n)
                .map(|j| centroid[j] + t * (simplex[n][j] - centroid[j]))
                .collect()
        };
        let xr = along(-1.0);
        let fr = f(&xr);
        evals += 1;
        if fr < values[0] {
            let xe = along(-2.0);
            let fe = f(&xe);
            evals += 1;
            if fe < fr {
                simplex[n] = xe;
                values[n] = fe;
            } else {
                simplex[n] = xr;
                values[n] = fr;
            }
        } else if fr < values[n - 1] {
            simplex[n] = xr;
            values[n] = fr;
        } else {
            let (xc, fc) = if fr < values[n] {
                let x = along(-0.5);
                let v = f(&x);
                (x, v)
            } else {
                let x = along(0.5);
                let v = f(&x);
                (x, v)
            };
            evals += 1;
            if fc < values[n].min(fr) {
                simplex[n] = xc;
                values[n] = fc;
            } else {
                // shrink toward the best point
                let best = simplex[0].clone();
                for i in 1..=n {
                    for (v, &b) in simplex[i].iter_mut().zip(&best) {
                        *v = b + 0.5 * (*v - b);
                    }
                    values[i] = f(&simplex[i]);
                }
                evals += n;
            }
        }
    }
    let best = (0..=n)
        .min_by(|&a, &b| values[a].total_cmp(&values[b]))
        .unwrap_or(0);
    (simplex[best].clone(), values[best], evals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_minimum_of_a_skewed_quadratic_and_rosenbrock() {
        let q = |x: &[f64]| (x[0] - 1.0).powi(2) + 10.0 * (x[1] + 2.0 + 0.5 * x[0]).powi(2) + 0.1;
        let (x, v, _) = nelder_mead(q, &[0.0, 0.0], &[0.5, 0.5], 500, &[1e-6, 1e-6], 1e-12);
        assert!(
            (x[0] - 1.0).abs() < 1e-4 && (x[1] + 2.5).abs() < 1e-4 && (v - 0.1).abs() < 1e-8,
            "{x:?}"
        );
        let rosen = |x: &[f64]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2);
        let (x, _, evals) =
            nelder_mead(rosen, &[-1.2, 1.0], &[0.1, 0.1], 2000, &[1e-7, 1e-7], 1e-14);
        assert!(
            (x[0] - 1.0).abs() < 1e-3 && (x[1] - 1.0).abs() < 1e-3 && evals <= 2000,
            "{x:?}"
        );
    }
}
