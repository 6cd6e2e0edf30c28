//! The one error type of the I/O layer. Every message starts with the file
//! path, then says what is wrong in words a user can act on.

use std::path::{Path, PathBuf};

use cassi_core::CassiError;
use thiserror::Error;

use crate::escape::esc;

/// Everything that can go wrong reading, describing or writing a file.
///
/// Each variant carries the path, and its `Display` text names it first, so a
/// CLI can print the error as it is.
#[derive(Debug, Error)]
pub enum IoError {
    /// The file (or, for a write, its directory) does not exist.
    #[error("{}: no such file", .path.display())]
    NotFound { path: PathBuf },

    /// The operating system refused or failed a read.
    #[error("{}: cannot read: {cause}", .path.display())]
    Read {
        path: PathBuf,
        cause: std::io::Error,
    },

    /// The operating system refused or failed a write (nothing was left at `path`).
    #[error("{}: cannot write: {cause}", .path.display())]
    Write {
        path: PathBuf,
        cause: std::io::Error,
    },

    /// The file ends before the data its headers announce.
    #[error("{}: truncated {format}: {}", .path.display(), esc(.detail))]
    Truncated {
        path: PathBuf,
        format: &'static str,
        detail: String,
    },

    /// The file is not valid in its format; `detail` holds the parser's message.
    #[error("{}: not a valid {format}: {}", .path.display(), esc(.detail))]
    Corrupt {
        path: PathBuf,
        format: &'static str,
        detail: String,
    },

    /// The extension (or content) matches no supported format.
    #[error("{}: unknown file format: {}", .path.display(), esc(.detail))]
    UnknownFormat { path: PathBuf, detail: String },

    /// No variable of that name; `present` lists what the file holds, with shapes.
    #[error("{}: no variable named '{}'; the file holds: {}", .path.display(), esc(.name), esc(.present))]
    VariableNotFound {
        path: PathBuf,
        name: String,
        present: String,
    },

    /// No name was given and the file does not hold exactly one numeric variable.
    #[error("{}: {}; choose one by name. The file holds: {}", .path.display(), esc(.reason), esc(.present))]
    AmbiguousVariable {
        path: PathBuf,
        reason: String,
        present: String,
    },

    /// The variable exists but its element type cannot be read as numbers.
    #[error("{}: variable '{}' has unsupported element type {}{}", .path.display(), esc(.name), esc(.dtype), esc(&hint_suffix(.hint)))]
    UnsupportedType {
        path: PathBuf,
        name: String,
        dtype: String,
        hint: String,
    },

    /// The variable has the wrong number of dimensions or sizes.
    #[error("{}: variable '{}' has shape {got}, expected {expected}", .path.display(), esc(.name))]
    Shape {
        path: PathBuf,
        name: String,
        got: String,
        expected: String,
    },

    /// The band axis of a 3-D array cannot be told from its shape.
    #[error(
        "{}: cannot tell which axis of variable '{}' (shape {shape}) holds the bands; \
         give the layout explicitly: --layout brc for (bands, rows, cols), \
         --layout rcb for (rows, cols, bands)", .path.display(), esc(.name)
    )]
    AmbiguousLayout {
        path: PathBuf,
        name: String,
        shape: String,
    },

    /// NaN or ±Inf in data that must be finite. `index` is 0-based, in the
    /// variable's own axis order as the file shows it.
    #[error("{}: variable '{}' contains a non-finite value ({value}) at index {index}", .path.display(), esc(.name))]
    NonFinite {
        path: PathBuf,
        name: String,
        value: f64,
        index: String,
    },

    /// A finite value too large for f32 (the element type of every cassi array).
    #[error("{}: variable '{}' holds {value} at index {index}, outside the range of f32", .path.display(), esc(.name))]
    OutOfRange {
        path: PathBuf,
        name: String,
        value: f64,
        index: String,
    },

    /// A caller-supplied argument that cannot be used (e.g. an invalid
    /// MATLAB variable name, an empty image).
    #[error("{}: {}", .path.display(), esc(.reason))]
    InvalidArgument { path: PathBuf, reason: String },

    /// An error of the science layer while building a core type from file data.
    #[error("{}: {}", .path.display(), esc(&.cause.to_string()))]
    Core { path: PathBuf, cause: CassiError },
}

fn hint_suffix(hint: &str) -> String {
    if hint.is_empty() {
        String::new()
    } else {
        format!(" ({hint})")
    }
}

impl IoError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            IoError::NotFound { path }
            | IoError::Read { path, .. }
            | IoError::Write { path, .. }
            | IoError::Truncated { path, .. }
            | IoError::Corrupt { path, .. }
            | IoError::UnknownFormat { path, .. }
            | IoError::VariableNotFound { path, .. }
            | IoError::AmbiguousVariable { path, .. }
            | IoError::UnsupportedType { path, .. }
            | IoError::Shape { path, .. }
            | IoError::AmbiguousLayout { path, .. }
            | IoError::NonFinite { path, .. }
            | IoError::OutOfRange { path, .. }
            | IoError::InvalidArgument { path, .. }
            | IoError::Core { path, .. } => path,
        }
    }

    /// Maps an OS error of a read to `NotFound` or `Read`.
    pub(crate) fn from_read(path: &Path, source: std::io::Error) -> Self {
        if source.kind() == std::io::ErrorKind::NotFound {
            IoError::NotFound {
                path: path.to_path_buf(),
            }
        } else {
            IoError::Read {
                path: path.to_path_buf(),
                cause: source,
            }
        }
    }

    pub(crate) fn write(path: &Path, source: std::io::Error) -> Self {
        IoError::Write {
            path: path.to_path_buf(),
            cause: source,
        }
    }

    pub(crate) fn core(path: &Path, source: CassiError) -> Self {
        IoError::Core {
            path: path.to_path_buf(),
            cause: source,
        }
    }
}

pub type Result<T> = std::result::Result<T, IoError>;
