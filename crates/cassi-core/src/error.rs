//! The one error type of the science layer. Messages name the thing, the value
//! or shape it had and what was wanted, so a CLI can print them as they are.

use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum CassiError {
    /// A scalar parameter outside its valid range.
    #[error("invalid parameter {name} = {}: {reason}", compact(*.value))]
    InvalidParameter {
        name: &'static str,
        value: f64,
        reason: String,
    },
    /// An array whose shape does not fit where it is used.
    #[error("{what} has shape {got}, expected {expected}")]
    Shape {
        what: String,
        got: String,
        expected: String,
    },
    /// NaN or ±Inf inside data that must be finite.
    #[error("{what} contains a non-finite value ({value}) at {location}")]
    NonFinite {
        what: String,
        value: f32,
        location: String,
    },
    /// An array or a problem larger than the element budget (see [`crate::limits`]).
    #[error("{what} is too large: {detail}")]
    TooLarge { what: String, detail: String },
    /// Data that has the right shape but cannot mean anything (an all-zero
    /// measurement, a mask with no open pixel, …).
    #[error("{what}: {reason}")]
    Meaningless { what: String, reason: String },
    /// Work stopped because its caller asked (a cancel flag was raised).
    #[error("{what}: stopped on request")]
    Cancelled { what: String },
}

pub type Result<T> = std::result::Result<T, CassiError>;

/// A value as a person reads it: 1.5, 0.001, 1e308, 1e-300 (not 309 digits).
fn compact(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

pub(crate) fn shape_error(
    what: impl Into<String>,
    got: impl Into<String>,
    expected: impl Into<String>,
) -> CassiError {
    CassiError::Shape {
        what: what.into(),
        got: got.into(),
        expected: expected.into(),
    }
}
