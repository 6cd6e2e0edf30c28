//! Input checks shared by the figures: every problem becomes a clear
//! [`FigureError::InvalidInput`](super::FigureError::InvalidInput), never a panic.

use super::error::{Result, invalid};

/// `len` must be positive.
pub(crate) fn nonempty(figure: &'static str, what: &str, len: usize) -> Result<()> {
    if len == 0 {
        Err(invalid(figure, format!("{what} is empty")))
    } else {
        Ok(())
    }
}

/// `got` must equal `expected`.
pub(crate) fn same_len(
    figure: &'static str,
    what: &str,
    got: usize,
    expected: usize,
    of_what: &str,
) -> Result<()> {
    if got != expected {
        Err(invalid(
            figure,
            format!("{what} has {got} values, expected {expected} (one per {of_what})"),
        ))
    } else {
        Ok(())
    }
}

/// Every value must be finite.
pub(crate) fn finite<'a>(
    figure: &'static str,
    what: &str,
    values: impl IntoIterator<Item = &'a f64>,
) -> Result<()> {
    match values.into_iter().enumerate().find(|(_, v)| !v.is_finite()) {
        Some((i, v)) => Err(invalid(figure, format!("{what}[{i}] is {v}, not finite"))),
        None => Ok(()),
    }
}

/// Every (x, y) point must be finite.
pub(crate) fn finite_points(figure: &'static str, what: &str, points: &[(f64, f64)]) -> Result<()> {
    match points
        .iter()
        .enumerate()
        .find(|(_, (x, y))| !x.is_finite() || !y.is_finite())
    {
        Some((i, (x, y))) => Err(invalid(
            figure,
            format!("{what}[{i}] = ({x}, {y}) is not finite"),
        )),
        None => Ok(()),
    }
}

/// A computed axis range must be something plotters can draw: finite, and
/// wide enough relative to its values to be resolved in f64 (data such as
/// ±1e308, or 1e16 and 1e16 + 1, are refused rather than drawn wrongly).
pub(crate) fn plottable(
    figure: &'static str,
    what: &str,
    (a, b): (f64, f64),
) -> Result<(f64, f64)> {
    let span = b - a;
    if a.is_finite() && b.is_finite() && span.is_finite() && span > 1e-9 * (a.abs() + b.abs()) {
        Ok((a, b))
    } else {
        Err(invalid(
            figure,
            format!("the {what} values need an axis range ({a}, {b}) that cannot be drawn"),
        ))
    }
}

/// An optional explicit axis range must be finite and increasing.
pub(crate) fn range(figure: &'static str, what: &str, r: Option<(f64, f64)>) -> Result<()> {
    match r {
        Some((lo, hi)) if !(lo.is_finite() && hi.is_finite() && lo < hi) => Err(invalid(
            figure,
            format!("{what} ({lo}, {hi}) must be finite with min < max"),
        )),
        _ => Ok(()),
    }
}
