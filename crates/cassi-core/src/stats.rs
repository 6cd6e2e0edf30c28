//! Summary statistics and the distribution functions the calibration's
//! error bars need: Student's t quantile (a mean of a few snapshots, its
//! spread estimated from them) and the χ² survival function (do snapshots
//! agree within their errors).

/// The median (the mean of the middle two for an even count); NaN when
/// `v` is empty.
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => s[n / 2],
        _ => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// ln Γ(x), x > 0.
fn ln_gamma(x: f64) -> f64 {
    libm::lgamma(x)
}

/// The regularised incomplete beta function I_x(a, b), 0 ≤ x ≤ 1, by its
/// continued fraction (modified Lentz), on the side where it converges fast.
fn incomplete_beta(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front =
        (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(x, a, b) / a
    } else {
        1.0 - front * beta_fraction(1.0 - x, b, a) / b
    }
}

fn beta_fraction(x: f64, a: f64, b: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut c = 1.0;
    let mut d = 1.0 - (a + b) * x / (a + 1.0);
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..300 {
        let m = m as f64;
        let m2 = 2.0 * m;
        for numerator in [
            m * (b - m) * x / ((a + m2 - 1.0) * (a + m2)),
            -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0)),
        ] {
            d = 1.0 + numerator * d;
            if d.abs() < TINY {
                d = TINY;
            }
            c = 1.0 + numerator / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            h *= d * c;
        }
        if (d * c - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// P(T ≤ t) for Student's t with `dof` degrees of freedom.
pub fn student_t_cdf(t: f64, dof: f64) -> f64 {
    let tail = 0.5 * incomplete_beta(dof / (dof + t * t), 0.5 * dof, 0.5);
    if t >= 0.0 { 1.0 - tail } else { tail }
}

/// The t with P(|T| ≤ t) = `coverage` (two-sided) for Student's t with
/// `dof` degrees of freedom: the factor on an estimated standard error
/// that makes an interval of this coverage. `coverage` in (0, 1).
pub fn student_t_two_sided(coverage: f64, dof: f64) -> f64 {
    let target = 0.5 + 0.5 * coverage.clamp(0.0, 1.0 - 1e-12);
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while student_t_cdf(hi, dof) < target {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if student_t_cdf(mid, dof) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The regularised upper incomplete gamma function Q(a, x).
fn upper_incomplete_gamma(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let front = (-x + a * x.ln() - ln_gamma(a)).exp();
    if x < a + 1.0 {
        // series for P
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * front
    } else {
        // continued fraction for Q (modified Lentz)
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let step = d * c;
            h *= step;
            if (step - 1.0).abs() < 1e-16 {
                break;
            }
        }
        front * h
    }
}

/// P(X ≥ `x`) for X ~ χ² with `dof` degrees of freedom.
pub fn chi_squared_sf(x: f64, dof: f64) -> f64 {
    upper_incomplete_gamma(0.5 * dof, 0.5 * x).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the tables (e.g. NIST/SEMATECH e-Handbook, 1.3.6.7.2–3).
    #[test]
    fn the_t_quantiles_are_the_tables() {
        for (dof, t975) in [
            (1.0, 12.706),
            (2.0, 4.303),
            (4.0, 2.776),
            (9.0, 2.262),
            (30.0, 2.042),
        ] {
            let t = student_t_two_sided(0.95, dof);
            assert!((t - t975).abs() < 1e-3, "dof {dof}: {t} for {t975}");
        }
        // 68.27 % (±1σ of a normal): t_0.8413 = 1.142 at 4 dof, → 1 as dof grows
        assert!((student_t_two_sided(0.6827, 4.0) - 1.142).abs() < 2e-3);
        assert!((student_t_two_sided(0.6827, 1e6) - 1.0).abs() < 1e-3);
        // the cdf is symmetric
        assert!((student_t_cdf(-1.3, 3.0) + student_t_cdf(1.3, 3.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_median_is_the_middle_value_or_the_middle_pair_s_mean() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn the_chi_squared_tail_is_the_tables() {
        for (x, dof, p) in [
            (3.841, 1.0, 0.05),
            (9.488, 4.0, 0.05),
            (13.277, 4.0, 0.01),
            (0.711, 4.0, 0.95),
            (4.0, 4.0, 0.406),
        ] {
            let q = chi_squared_sf(x, dof);
            assert!((q - p).abs() < 1e-3, "χ²({dof}) ≥ {x}: {q} for {p}");
        }
        assert_eq!(chi_squared_sf(0.0, 3.0), 1.0);
    }
}
