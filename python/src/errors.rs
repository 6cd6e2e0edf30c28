//! Library errors as Python exceptions.
//!
//! `cassi.CassiError` is the base of every exception this module raises;
//! `cassi.InputError` (also a `ValueError`) is bad input (a shape, a value,
//! NaN/±Inf, a file's content), `cassi.InputTypeError` (also a `TypeError`)
//! an argument of the wrong kind, `cassi.FileNotFound` (also a
//! `FileNotFoundError`) a missing file and `cassi.FileError` (also an
//! `OSError`) a read or write the system refused. Messages are the library's
//! own: they name the file, variable, parameter and shapes.

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

use cassi_core::CassiError;
use cassi_io::IoError;

/// What went wrong inside the library, carried out of a GIL-free section
/// and turned into a Python exception once the GIL is held again.
#[derive(Debug)]
pub enum Failure {
    Core(CassiError),
    Io(IoError),
    /// A panic caught at the boundary: a bug, never a crash of Python.
    Internal(String),
    /// A whole job (a study) failed: its message carries the context chain
    /// (which scene, which shard); the exception class follows the library
    /// error underneath.
    Study(anyhow::Error),
}

impl From<CassiError> for Failure {
    fn from(e: CassiError) -> Self {
        Self::Core(e)
    }
}

impl From<IoError> for Failure {
    fn from(e: IoError) -> Self {
        Self::Io(e)
    }
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> Self {
        Python::attach(|py| match f {
            Failure::Core(e) => raise(py, Kind::Value, e.to_string()),
            Failure::Study(e) => {
                let kind = if let Some(io) = e.chain().find_map(|c| c.downcast_ref::<IoError>()) {
                    io_kind(io)
                } else {
                    Kind::Value
                };
                raise(py, kind, format!("{e:#}"))
            }
            Failure::Io(e) => raise(py, io_kind(&e), e.to_string()),
            Failure::Internal(msg) => raise(
                py,
                Kind::Base,
                format!("internal error (a bug in cassi; please report it): {msg}"),
            ),
        })
    }
}

/// The exception class of a file error.
fn io_kind(e: &IoError) -> Kind {
    match e {
        IoError::NotFound { .. } => Kind::NotFound,
        // a write into a folder that does not exist
        IoError::Read { cause, .. } | IoError::Write { cause, .. }
            if cause.kind() == std::io::ErrorKind::NotFound =>
        {
            Kind::NotFound
        }
        IoError::Read { .. } | IoError::Write { .. } => Kind::Os,
        _ => Kind::Value,
    }
}

/// Which of the module's exception classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Base,
    Value,
    Type,
    NotFound,
    Os,
}

/// The classes, made once when the module is imported.
struct Classes {
    base: Py<PyType>,
    value: Py<PyType>,
    type_: Py<PyType>,
    not_found: Py<PyType>,
    os: Py<PyType>,
}

static CLASSES: PyOnceLock<Classes> = PyOnceLock::new();

fn make_class(
    py: Python<'_>,
    name: &str,
    bases: Bound<'_, PyTuple>,
    doc: &str,
) -> PyResult<Py<PyType>> {
    let ns = PyDict::new(py);
    ns.set_item("__module__", "cassi")?;
    ns.set_item("__doc__", doc)?;
    let builtins = py.import("builtins")?;
    let cls = builtins.getattr("type")?.call1((name, bases, ns))?;
    Ok(cls.cast_into::<PyType>()?.unbind())
}

fn classes(py: Python<'_>) -> PyResult<&Classes> {
    CLASSES.get_or_try_init(py, || {
        let builtins = py.import("builtins")?;
        let b = |n: &str| builtins.getattr(n);
        let base = make_class(
            py,
            "CassiError",
            PyTuple::new(py, [b("Exception")?])?,
            "Base class of every error cassi raises; the message is the library's own \
             (it names the file, variable, parameter and the shapes involved).",
        )?;
        let sub = |name: &str, builtin: &str, doc: &str| -> PyResult<Py<PyType>> {
            make_class(
                py,
                name,
                PyTuple::new(py, [base.bind(py).clone().into_any(), b(builtin)?])?,
                doc,
            )
        };
        Ok(Classes {
            value: sub(
                "InputError",
                "ValueError",
                "Input cassi cannot use: a wrong shape, a value out of range, NaN/±Inf, an \
                 unknown name, or a file whose content is not what was asked for.",
            )?,
            type_: sub(
                "InputTypeError",
                "TypeError",
                "An argument of a kind cassi cannot read (e.g. a complex or object array).",
            )?,
            not_found: sub(
                "FileNotFound",
                "FileNotFoundError",
                "A file (or the folder of an output file) does not exist.",
            )?,
            os: sub(
                "FileError",
                "OSError",
                "The operating system refused or failed a read or a write.",
            )?,
            base,
        })
    })
}

/// Adds the classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let c = classes(py)?;
    for cls in [&c.base, &c.value, &c.type_, &c.not_found, &c.os] {
        let cls = cls.bind(py);
        m.add(cls.name()?, cls)?;
    }
    Ok(())
}

/// The exception of `kind` with `message`.
pub fn raise(py: Python<'_>, kind: Kind, message: impl Into<String>) -> PyErr {
    let message = message.into();
    let c = match classes(py) {
        Ok(c) => c,
        Err(e) => return e,
    };
    let cls = match kind {
        Kind::Base => &c.base,
        Kind::Value => &c.value,
        Kind::Type => &c.type_,
        Kind::NotFound => &c.not_found,
        Kind::Os => &c.os,
    };
    PyErr::from_type(cls.bind(py).clone(), message)
}

/// An `InputError` (a `ValueError`) with `message`.
pub fn value_error(py: Python<'_>, message: impl Into<String>) -> PyErr {
    raise(py, Kind::Value, message)
}

/// An `InputTypeError` (a `TypeError`) with `message`.
pub fn type_error(py: Python<'_>, message: impl Into<String>) -> PyErr {
    raise(py, Kind::Type, message)
}

/// Runs `f` without the GIL, a panic caught and reported as a `CassiError`.
pub fn compute<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: Send + FnOnce() -> Result<T, Failure>,
{
    let out = py.detach(|| catch(f));
    out.map_err(PyErr::from)
}

/// `f()`, a panic turned into [`Failure::Internal`].
pub fn catch<T>(f: impl FnOnce() -> Result<T, Failure>) -> Result<T, Failure> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => Err(Failure::Internal(panic_message(payload.as_ref()))),
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic without a message".into()
    }
}
