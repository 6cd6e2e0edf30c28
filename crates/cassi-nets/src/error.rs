//! The one error type of cassi-nets. Checkpoint errors name the file; weight
//! mismatches list every missing, unexpected and mis-shaped tensor at once.

use std::path::PathBuf;

use thiserror::Error;

#[derive(Debug, Error)]
pub enum NetError {
    /// A checkpoint file that cannot be read or parsed.
    #[error("{}: {msg}", path.display())]
    Checkpoint { path: PathBuf, msg: String },
    /// Checkpoint tensors that do not match what a network expects.
    #[error("{}: the tensors do not match {net}:\n{report}", path.display())]
    WeightMismatch {
        path: PathBuf,
        net: String,
        report: String,
    },
    /// A network input of the wrong shape or size.
    #[error("{what} has shape {got}, expected {expected}")]
    Input {
        what: String,
        got: String,
        expected: String,
    },
    /// An error of the optics or a solver (a recipe built on cassi-core).
    #[error(transparent)]
    Core(#[from] cassi_core::CassiError),
}

pub type Result<T> = std::result::Result<T, NetError>;

/// "[28, 28, 3, 3]" — shapes print the way PyTorch shows them.
pub(crate) fn shape_str(shape: &[usize]) -> String {
    format!("{shape:?}")
}

/// A cassi-nets error as the science layer's, with the same message: what
/// a [`cassi_core::recon::Reconstructor`] returns.
impl From<NetError> for cassi_core::CassiError {
    fn from(e: NetError) -> Self {
        use cassi_core::CassiError;
        match e {
            NetError::Core(e) => e,
            NetError::Input {
                what,
                got,
                expected,
            } => CassiError::Shape {
                what,
                got,
                expected,
            },
            NetError::Checkpoint { path, msg } => CassiError::Meaningless {
                what: path.display().to_string(),
                reason: msg,
            },
            NetError::WeightMismatch { path, net, report } => CassiError::Meaningless {
                what: path.display().to_string(),
                reason: format!("the tensors do not match {net}:\n{report}"),
            },
        }
    }
}
