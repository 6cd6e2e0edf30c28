//! MATLAB v7.3 MAT-files: HDF5 behind a 512-byte user block holding the
//! MATLAB header, read with the pure-Rust `hdf5-reader`.
//!
//! MATLAB writes each variable as a root-level dataset with a `MATLAB_class`
//! attribute. MATLAB is column-major and HDF5 row-major, so a MATLAB array of
//! size (r, c, b) appears in HDF5 with dims (b, c, r) and the same bytes; we
//! report MATLAB's size and reorder the values into row-major order of it.
//! Structs are groups; names beginning with `#` (`#refs#`, `#subsystem#`) are
//! MATLAB internals and are skipped.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use hdf5_reader::{Dataset, Datatype, Hdf5File};

use crate::array::{VarInfo, col_major_to_row_major};
use crate::error::{IoError, Result};

const FORMAT: &str = "MATLAB v7.3 MAT-file (HDF5)";

fn corrupt(path: &Path, detail: impl Into<String>) -> IoError {
    IoError::Corrupt {
        path: path.to_path_buf(),
        format: FORMAT,
        detail: detail.into(),
    }
}

/// Runs a closure calling into `hdf5-reader`, turning a panic inside the
/// parser (which should not happen: it is hardened against malformed input)
/// into an error rather than a crash.
fn guarded<T>(path: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(corrupt(path, format!("the HDF5 parser failed: {msg}")))
        }
    }
}

fn h5err(path: &Path, e: hdf5_reader::error::Error) -> IoError {
    let msg = e.to_string();
    let lower = msg.to_lowercase();
    if lower.contains("eof")
        || lower.contains("end of file")
        || lower.contains("end of data")
        || lower.contains("out of bounds")
        || lower.contains("beyond")
        || lower.contains("truncat")
    {
        IoError::Truncated {
            path: path.to_path_buf(),
            format: FORMAT,
            detail: msg,
        }
    } else {
        corrupt(path, msg)
    }
}

const NUMERIC_CLASSES: [&str; 11] = [
    "double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
    "logical",
];

fn h5_type_name(dt: &Datatype) -> String {
    match dt {
        Datatype::FloatingPoint { size, .. } => format!("float{}", 8 * *size as usize),
        Datatype::FixedPoint { size, signed, .. } => {
            format!(
                "{}int{}",
                if *signed { "" } else { "u" },
                8 * *size as usize
            )
        }
        Datatype::Compound { .. } => "compound".into(),
        Datatype::String { .. } => "string".into(),
        Datatype::Reference { .. } => "reference".into(),
        other => format!("{other:?}")
            .split([' ', '{', '('])
            .next()
            .unwrap_or("other")
            .to_lowercase(),
    }
}

fn attr_string(ds: &Dataset, name: &str) -> Option<String> {
    ds.attribute(name).ok()?.read_string().ok()
}

fn attr_nonzero(ds: &Dataset, name: &str) -> bool {
    ds.attribute(name)
        .ok()
        .and_then(|a| a.read_as_f64().ok())
        .is_some_and(|v| v != 0.0)
}

fn dataset_info(ds: &Dataset) -> VarInfo {
    let name = ds.name().trim_start_matches('/').to_string();
    let name = name.rsplit('/').next().unwrap_or(&name).to_string();
    let dt = ds.dtype();
    let class = attr_string(ds, "MATLAB_class");
    let mut shape: Vec<usize> = ds.shape().iter().rev().map(|&d| d as usize).collect();
    let empty = attr_nonzero(ds, "MATLAB_empty");
    if empty {
        // MATLAB stores an empty array as a dataset holding its size.
        shape = ds
            .read_array::<u64>()
            .map(|a| a.iter().map(|&d| d as usize).collect())
            .unwrap_or_else(|_| vec![0, 0]);
    }
    let is_number = matches!(
        dt,
        Datatype::FloatingPoint { .. } | Datatype::FixedPoint { .. }
    );
    let (dtype, numeric, note) = match class.as_deref() {
        Some(c) if NUMERIC_CLASSES.contains(&c) && is_number => {
            (c.to_string(), true, String::new())
        }
        Some(c) if NUMERIC_CLASSES.contains(&c) && matches!(dt, Datatype::Compound { .. }) => (
            format!("complex {c}"),
            false,
            "complex values are not supported; save real(x) or abs(x)".to_string(),
        ),
        Some(c) if attr_nonzero(ds, "MATLAB_sparse") || c == "sparse" => (
            c.to_string(),
            false,
            "sparse matrices are not supported; save full(x)".to_string(),
        ),
        Some(c) => (
            c.to_string(),
            false,
            format!("a MATLAB {c} is not a numeric array"),
        ),
        // A plain HDF5 dataset without MATLAB's attribute.
        None if is_number => (h5_type_name(dt), true, String::new()),
        None => (
            h5_type_name(dt),
            false,
            format!("HDF5 type {} is not numeric", h5_type_name(dt)),
        ),
    };
    VarInfo {
        name,
        shape,
        dtype,
        numeric,
        note,
    }
}

/// An opened v7.3 file.
pub(crate) struct Mat73 {
    vars: Vec<VarInfo>,
    /// Per variable: its HDF5 dataset and whether it is a MATLAB empty, or
    /// None for a group.
    datasets: Vec<Option<(Dataset, bool)>>,
}

impl Mat73 {
    pub(crate) fn parse(path: &Path, bytes: Vec<u8>) -> Result<Self> {
        guarded(path, || {
            let file = Hdf5File::from_vec(bytes).map_err(|e| h5err(path, e))?;
            let root = file.root_group().map_err(|e| h5err(path, e))?;
            let (groups, datasets) = root.members().map_err(|e| h5err(path, e))?;
            let mut vars = Vec::new();
            let mut sets = Vec::new();
            for ds in &datasets {
                let info = dataset_info(ds);
                if info.name.starts_with('#') {
                    continue;
                }
                let empty = attr_nonzero(ds, "MATLAB_empty");
                sets.push(Some((ds.clone(), empty)));
                vars.push(info);
            }
            for g in &groups {
                let name = g.name().trim_start_matches('/').to_string();
                if name.starts_with('#') {
                    continue;
                }
                let class = g
                    .attribute("MATLAB_class")
                    .ok()
                    .and_then(|a| a.read_string().ok())
                    .unwrap_or_else(|| "group".to_string());
                vars.push(VarInfo {
                    name,
                    shape: Vec::new(),
                    note: format!("a MATLAB {class} is not a numeric array"),
                    dtype: class,
                    numeric: false,
                });
                sets.push(None);
            }
            Ok(Mat73 {
                vars,
                datasets: sets,
            })
        })
    }

    pub(crate) fn vars(&self) -> Vec<VarInfo> {
        self.vars.clone()
    }

    /// Decodes variable `i` into f64 values in row-major order of its MATLAB size.
    pub(crate) fn read(&self, path: &Path, i: usize) -> Result<Vec<f64>> {
        let (Some(info), Some(Some((ds, empty)))) = (self.vars.get(i), self.datasets.get(i)) else {
            return Err(corrupt(path, format!("variable #{i} is not a dataset")));
        };
        if *empty {
            return Ok(Vec::new());
        }
        guarded(path, || {
            let e = |err| h5err(path, err);
            // HDF5 C order of the reversed dims = MATLAB column-major order.
            let colmajor: Vec<f64> = match ds.dtype() {
                Datatype::FloatingPoint { size: 8, .. } => {
                    ds.read_array::<f64>().map_err(e)?.iter().copied().collect()
                }
                Datatype::FloatingPoint { size: 4, .. } => ds
                    .read_array::<f32>()
                    .map_err(e)?
                    .iter()
                    .map(|&v| v as f64)
                    .collect(),
                Datatype::FixedPoint { size, signed, .. } => match (size, signed) {
                    (1, false) => conv(ds.read_array::<u8>().map_err(e)?.iter()),
                    (1, true) => conv(ds.read_array::<i8>().map_err(e)?.iter()),
                    (2, false) => conv(ds.read_array::<u16>().map_err(e)?.iter()),
                    (2, true) => conv(ds.read_array::<i16>().map_err(e)?.iter()),
                    (4, false) => conv(ds.read_array::<u32>().map_err(e)?.iter()),
                    (4, true) => conv(ds.read_array::<i32>().map_err(e)?.iter()),
                    (8, false) => ds
                        .read_array::<u64>()
                        .map_err(e)?
                        .iter()
                        .map(|&v| v as f64)
                        .collect(),
                    (8, true) => ds
                        .read_array::<i64>()
                        .map_err(e)?
                        .iter()
                        .map(|&v| v as f64)
                        .collect(),
                    _ => return Err(unsupported(path, info)),
                },
                _ => return Err(unsupported(path, info)),
            };
            if Some(colmajor.len()) != crate::array::element_count(&info.shape) {
                return Err(corrupt(
                    path,
                    format!(
                        "variable '{}' holds {} values for size {:?}",
                        info.name,
                        colmajor.len(),
                        info.shape
                    ),
                ));
            }
            Ok(col_major_to_row_major(&colmajor, &info.shape))
        })
    }
}

fn conv<'a, T: Copy + Into<f64> + 'a>(it: impl Iterator<Item = &'a T>) -> Vec<f64> {
    it.map(|&v| v.into()).collect()
}

fn unsupported(path: &Path, info: &VarInfo) -> IoError {
    IoError::UnsupportedType {
        path: path.to_path_buf(),
        name: info.name.clone(),
        dtype: info.dtype.clone(),
        hint: String::new(),
    }
}
