//! The error type of the figure module.

use thiserror::Error;

/// Everything that can go wrong drawing a figure.
#[derive(Debug, Error)]
pub enum FigureError {
    /// The data cannot be drawn as given (empty, mismatched lengths, NaN, …).
    #[error("{figure}: invalid input: {reason}")]
    InvalidInput {
        figure: &'static str,
        reason: String,
    },
    /// The drawing library failed (should not happen with valid input).
    #[error("{figure}: drawing failed: {reason}")]
    Render {
        figure: &'static str,
        reason: String,
    },
    /// Writing the PNG failed.
    #[error(transparent)]
    Io(#[from] cassi_io::IoError),
}

/// The result type of the figure module.
pub type Result<T> = std::result::Result<T, FigureError>;

/// Builds an [`FigureError::InvalidInput`].
pub(crate) fn invalid(figure: &'static str, reason: impl Into<String>) -> FigureError {
    FigureError::InvalidInput {
        figure,
        reason: reason.into(),
    }
}
