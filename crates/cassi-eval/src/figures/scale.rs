//! Axis ranges: padded data extents rounded outward to tidy values.

/// A tidy step near `raw` (1, 2, 2.5 or 5 × 10^k).
pub(crate) fn nice_step(raw: f64) -> f64 {
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let p = 10f64.powf(raw.log10().floor());
    let f = raw / p;
    let m = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 2.5 {
        2.5
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    m * p
}

/// The extent (min, max) of finite values, or None when there are none.
pub(crate) fn extent(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// A span to use when all values are equal: 10 % of the magnitude, or 1.
fn flat_span(v: f64) -> f64 {
    if v == 0.0 { 1.0 } else { 0.2 * v.abs() }
}

/// An axis range around `(lo, hi)`: padded by `pad_lo`/`pad_hi` of the span
/// and rounded outward to a tidy step. Starts at 0 when the data are all
/// non-negative and 0 is close (within 40 % of the span below the minimum),
/// so that bars of positive quantities are not cut off needlessly, but a
/// range such as 25–38 dB does not waste most of the plot on 0–25.
pub(crate) fn axis_range(lo: f64, hi: f64, pad_lo: f64, pad_hi: f64) -> (f64, f64) {
    let span = if hi > lo { hi - lo } else { flat_span(hi) };
    let (mut a, mut b) = (lo - pad_lo * span, hi + pad_hi * span);
    if lo >= 0.0 && (a < 0.0 || lo <= 0.4 * span) {
        a = 0.0;
    }
    let step = nice_step((b - a) / 10.0);
    if a != 0.0 {
        a = (a / step).floor() * step;
    }
    b = (b / step).ceil() * step;
    if b <= a {
        b = a + step;
    }
    (a, b)
}

/// A range that keeps the data exactly as given (no rounding), padded by
/// `pad` of the span; for axes whose ends should hug the data (wavelengths,
/// category positions).
pub(crate) fn padded(lo: f64, hi: f64, pad: f64) -> (f64, f64) {
    let span = if hi > lo { hi - lo } else { flat_span(hi) };
    (lo - pad * span, hi + pad * span)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_bars_do_not_start_at_zero() {
        let (a, b) = axis_range(24.3, 37.9, 0.15, 0.12);
        assert!(a > 15.0 && a < 24.3, "{a}");
        assert!(b > 37.9 && b < 45.0, "{b}");
    }

    #[test]
    fn small_positive_values_start_at_zero() {
        assert_eq!(axis_range(0.1, 5.0, 0.1, 0.1).0, 0.0);
    }

    #[test]
    fn flat_and_negative_data_get_a_range() {
        let (a, b) = axis_range(3.0, 3.0, 0.1, 0.1);
        assert!(a < 3.0 && b > 3.0);
        let (a, b) = axis_range(-2.0, -1.0, 0.1, 0.1);
        assert!(a < -2.0 && b > -1.0);
        let (a, b) = axis_range(0.0, 0.0, 0.1, 0.1);
        assert!(a == 0.0 && b > 0.0);
    }

    #[test]
    fn steps_are_tidy() {
        assert_eq!(nice_step(0.7), 1.0);
        assert_eq!(nice_step(1.7), 2.0);
        assert_eq!(nice_step(23.0), 25.0);
        assert_eq!(nice_step(0.04), 0.05);
    }
}
