//! NumPy arrays in and out.
//!
//! Input: a C-contiguous float32 ndarray is read in place (a read-only
//! view, no copy); any other real array (another float width, integers,
//! bools, a strided or Fortran-ordered view, a nested list) is converted to
//! a C-contiguous float32 copy by NumPy; complex, object and string data are
//! refused. Every input is checked for NaN/±Inf and its shape before use.
//! Output: arrays that own the library's buffers (no copy).

use cassi_io::numpy_shape;
use numpy::{
    IntoPyArray, PyArray1, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use rayon::prelude::*;

use cassi_core::error::CassiError;
use cassi_core::{Cube, Frame};

use crate::errors::{type_error, value_error};

/// A float32 C-contiguous array borrowed read-only from Python.
pub struct F32Array<'py> {
    array: PyReadonlyArrayDyn<'py, f32>,
    /// Whether it is a converted copy rather than the caller's own buffer.
    pub copied: bool,
}

impl<'py> F32Array<'py> {
    pub fn shape(&self) -> &[usize] {
        self.array.shape()
    }

    /// The values in C order; the caller's own memory when not `copied`.
    pub fn slice(&self) -> &[f32] {
        // C-contiguity was checked (or made) when the array was taken
        self.array
            .as_slice()
            .expect("a C-contiguous array has a slice")
    }

    /// The address of the first value (the zero-copy check in the tests).
    pub fn data_ptr(&self) -> usize {
        self.slice().as_ptr() as usize
    }
}

/// `obj` as float32 C-contiguous (see the module doc), named `what` in errors.
pub fn f32_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<F32Array<'py>> {
    let py = obj.py();
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>()
        && a.is_c_contiguous()
    {
        return Ok(F32Array {
            array: readonly(a, what)?,
            copied: false,
        });
    }
    let np = py.import("numpy")?;
    let arr = if obj.cast::<PyUntypedArray>().is_ok() {
        obj.clone()
    } else {
        np.call_method1("asarray", (obj,)).map_err(|e| {
            type_error(
                py,
                format!("{what}: cannot be read as an array ({e}); pass a NumPy array"),
            )
        })?
    };
    let untyped = arr.cast::<PyUntypedArray>()?;
    let dtype = untyped.dtype();
    match dtype.kind() {
        b'f' | b'i' | b'u' | b'b' => {}
        _ => {
            return Err(type_error(
                py,
                format!(
                    "{what} has dtype {}; cassi takes real numbers: float32 (used in place when \
                     C-contiguous), or float64/integer/bool arrays (converted to float32)",
                    dtype.str()?
                ),
            ));
        }
    }
    let converted = np.call_method1("ascontiguousarray", (arr, np.getattr("float32")?))?;
    let a = converted.cast_into::<PyArrayDyn<f32>>()?;
    Ok(F32Array {
        array: readonly(&a, what)?,
        copied: true,
    })
}

fn readonly<'py>(
    a: &Bound<'py, PyArrayDyn<f32>>,
    what: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, f32>> {
    a.try_readonly().map_err(|e| {
        value_error(
            a.py(),
            format!("{what}: cannot be read while it is borrowed for writing ({e})"),
        )
    })
}

/// Refuses NaN/±Inf, naming `what` and the first bad index.
pub fn check_finite(py: Python<'_>, a: &F32Array<'_>, what: &str) -> PyResult<()> {
    let data = a.slice();
    let Some(i) = first_non_finite(py, data) else {
        return Ok(());
    };
    let shape = a.shape();
    let mut index = vec![0usize; shape.len()];
    let mut rest = i;
    for (axis, &n) in shape.iter().enumerate().rev() {
        index[axis] = rest % n.max(1);
        rest /= n.max(1);
    }
    let e = CassiError::NonFinite {
        what: what.to_string(),
        value: data[i],
        location: format!("index {}", numpy_shape(&index)),
    };
    Err(value_error(
        py,
        if a.copied {
            format!("{e} (after conversion to float32: values beyond ±3.4e38 become ±inf)")
        } else {
            e.to_string()
        },
    ))
}

/// The index of the first NaN/±Inf in `data`, if any. A branch-free scan
/// per block (exponent bits all set), the blocks on rayon's threads and
/// without the GIL, so the check costs a fraction of one operator
/// application even on a 256×256×28 cube.
fn first_non_finite(py: Python<'_>, data: &[f32]) -> Option<usize> {
    const BLOCK: usize = 1 << 14;
    let bad_block = |c: &[f32]| {
        c.iter().fold(0u32, |acc, v| {
            acc | u32::from(v.to_bits() & 0x7f80_0000 == 0x7f80_0000)
        }) != 0
    };
    let block = py.detach(|| {
        if data.len() < 4 * BLOCK {
            data.chunks(BLOCK).position(bad_block)
        } else {
            data.par_chunks(BLOCK).position_first(bad_block)
        }
    })?;
    let start = block * BLOCK;
    data[start..]
        .iter()
        .position(|v| !v.is_finite())
        .map(|i| start + i)
}

/// A shape error in the library's words.
pub fn shape_error(py: Python<'_>, what: &str, got: &[usize], expected: String) -> PyErr {
    value_error(
        py,
        CassiError::Shape {
            what: what.to_string(),
            got: numpy_shape(got),
            expected,
        }
        .to_string(),
    )
}

/// A finite array of exactly `expected` (named `layout`, e.g. "(bands, rows, cols)").
pub fn finite_with_shape<'py>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    expected: &[usize],
    why: &str,
) -> PyResult<F32Array<'py>> {
    let py = obj.py();
    let a = f32_array(obj, what)?;
    if a.shape() != expected {
        return Err(shape_error(
            py,
            what,
            a.shape(),
            format!("{} {why}", numpy_shape(expected)),
        ));
    }
    check_finite(py, &a, what)?;
    Ok(a)
}

/// A 2-D finite array as a [`Frame`] (a copy: the library's frames own their data).
pub fn frame(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Frame> {
    let py = obj.py();
    let a = f32_array(obj, what)?;
    let [rows, cols] = a.shape()[..] else {
        return Err(shape_error(
            py,
            what,
            a.shape(),
            "a 2-D array (rows, cols)".into(),
        ));
    };
    check_finite(py, &a, what)?;
    Frame::from_vec(rows, cols, a.slice().to_vec()).map_err(|e| value_error(py, e.to_string()))
}

/// A 3-D finite array (bands, rows, cols) as a [`Cube`] (a copy).
pub fn cube(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Cube> {
    let py = obj.py();
    let a = f32_array(obj, what)?;
    let [bands, rows, cols] = a.shape()[..] else {
        return Err(shape_error(
            py,
            what,
            a.shape(),
            "a 3-D array (bands, rows, cols)".into(),
        ));
    };
    check_finite(py, &a, what)?;
    Cube::from_vec(bands, rows, cols, a.slice().to_vec())
        .map_err(|e| value_error(py, e.to_string()))
}

/// `data` (C order) as an array of `shape`, owning the vector (no copy).
pub fn to_numpy<'py>(
    py: Python<'py>,
    data: Vec<f32>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    let flat: Bound<'py, PyArray1<f32>> = data.into_pyarray(py);
    Ok(flat.reshape(shape.to_vec())?.into_any())
}

pub fn cube_to_numpy(py: Python<'_>, cube: Cube) -> PyResult<Bound<'_, PyAny>> {
    let (l, h, w) = cube.shape();
    to_numpy(py, cube.into_vec(), &[l, h, w])
}

pub fn frame_to_numpy(py: Python<'_>, frame: Frame) -> PyResult<Bound<'_, PyAny>> {
    let (h, w) = frame.shape();
    to_numpy(py, frame.into_vec(), &[h, w])
}
