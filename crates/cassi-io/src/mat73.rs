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

use hdf5_reader::io::Cursor;
use hdf5_reader::messages::HdfMessage;
use hdf5_reader::messages::layout::DataLayout;
use hdf5_reader::object_header::ObjectHeader;
use hdf5_reader::{ByteOrder, Dataset, Datatype, Hdf5File, OpenOptions};

use crate::array::Elem;
use crate::array::{Endian, VarInfo};
use crate::decode::Sink;
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

/// The element type of a numeric HDF5 datatype.
fn h5_elem(dt: &Datatype) -> Option<Elem> {
    let e = |o: &ByteOrder| match o {
        ByteOrder::BigEndian => Endian::Big,
        _ => Endian::Little,
    };
    match dt {
        Datatype::FloatingPoint { size, byte_order } => {
            Elem::new('f', *size as usize, e(byte_order))
        }
        Datatype::FixedPoint {
            size,
            signed,
            byte_order,
        } => Elem::new(
            if *signed { 'i' } else { 'u' },
            *size as usize,
            e(byte_order),
        ),
        _ => None,
    }
}

fn dataset_info(ds: &Dataset) -> VarInfo {
    let name = ds.name().trim_start_matches('/').to_string();
    let name = name.rsplit('/').next().unwrap_or(&name).to_string();
    let dt = ds.dtype();
    let class = attr_string(ds, "MATLAB_class");
    let mut shape: Vec<usize> = ds.shape().iter().rev().map(|&d| d as usize).collect();
    let empty = attr_nonzero(ds, "MATLAB_empty");
    if empty {
        // MATLAB stores an empty array as a dataset holding its size (a
        // handful of numbers; a larger one is not an empty array's).
        shape = if ds.num_elements().is_ok_and(|n| n <= 32) {
            ds.read_array::<u64>()
                .map(|a| a.iter().map(|&d| d as usize).collect())
                .unwrap_or_else(|_| vec![0, 0])
        } else {
            vec![0, 0]
        };
    }
    let elem = h5_elem(dt);
    let is_number = elem.is_some();
    let half = matches!(dt, Datatype::FloatingPoint { size: 2, .. });
    let (dtype, numeric, note) = match class.as_deref() {
        // MATLAB has no half type: report what the file stores.
        _ if half => ("float16".to_string(), true, String::new()),
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
        elem: if numeric && !empty { elem } else { None },
        fortran: true,
        unstored: false,
        max_bytes: None,
    }
}

/// What the dataset's layout message says about its storage: whether any
/// is allocated, the element count of one chunk (for a chunked one), and
/// the bytes stored (for a compact or contiguous one, clamped to the file).
fn storage_of(file: &Hdf5File, ds: &Dataset, file_len: u64) -> (bool, Option<usize>, Option<u64>) {
    let sb = file.superblock();
    let Ok(header) = ObjectHeader::parse_at_storage_with_limit(
        file.storage(),
        ds.address(),
        sb.offset_size,
        sb.length_size,
        1 << 20,
    ) else {
        // hdf5-reader parsed it once already; a failure here shows on read.
        return (true, None, None);
    };
    let undefined = |a: u64| Cursor::is_undefined_offset(a, sb.offset_size);
    for m in &header.messages {
        if let HdfMessage::DataLayout(l) = m {
            return match &l.layout {
                DataLayout::Compact { data } => (true, None, Some(data.len() as u64)),
                DataLayout::Contiguous { address, size } => {
                    let stored = !undefined(*address) && *size > 0;
                    let start = sb.base_address.saturating_add(*address);
                    let present = file_len.saturating_sub(start).min(*size);
                    (stored, None, stored.then_some(present))
                }
                DataLayout::Chunked { address, dims, .. } => {
                    let chunk = dims
                        .iter()
                        .take(ds.ndim())
                        .try_fold(1usize, |n, &d| n.checked_mul(d as usize))
                        .unwrap_or(usize::MAX);
                    (!undefined(*address), Some(chunk), None)
                }
            };
        }
    }
    (true, None, None)
}

/// An opened v7.3 file.
pub(crate) struct Mat73 {
    vars: Vec<VarInfo>,
    /// Per variable: its HDF5 dataset and the element count of one chunk,
    /// or None for a group.
    datasets: Vec<Option<(Dataset, Option<usize>)>>,
}

impl Mat73 {
    pub(crate) fn parse(path: &Path, bytes: Vec<u8>) -> Result<Self> {
        guarded(path, || {
            // Our reads go into buffers we size (after the budget check);
            // the library's own allocations for one read call stay small,
            // and no chunk cache holds copies of what we already decoded.
            let options = OpenOptions::default()
                .with_chunk_cache_bytes(0)
                .with_max_read_bytes(64 << 20)
                .with_max_object_header_bytes(4 << 20);
            let file_len = bytes.len() as u64;
            let file =
                Hdf5File::from_vec_with_options(bytes, options).map_err(|e| h5err(path, e))?;
            let root = file.root_group().map_err(|e| h5err(path, e))?;
            let (groups, datasets) = root.members().map_err(|e| h5err(path, e))?;
            let mut vars = Vec::new();
            let mut sets = Vec::new();
            for ds in &datasets {
                let mut info = dataset_info(ds);
                if info.name.starts_with('#') {
                    continue;
                }
                let (stored, chunk, present) = storage_of(&file, ds, file_len);
                info.unstored = !stored;
                info.max_bytes = present;
                sets.push(Some((ds.clone(), chunk)));
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
                    note: format!("a MATLAB {class} is not a numeric array"),
                    dtype: class,
                    ..VarInfo::default()
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

    /// Hands variable `i`'s values (MATLAB column-major order, the file's
    /// byte order) to `sink`. The caller has checked the element count
    /// against the budget.
    pub(crate) fn stream(&self, path: &Path, i: usize, sink: &mut dyn Sink) -> Result<()> {
        let (Some(info), Some(Some((ds, chunk)))) = (self.vars.get(i), self.datasets.get(i)) else {
            return Err(corrupt(path, format!("variable #{i} is not a dataset")));
        };
        let Some(el) = info.elem else {
            // A MATLAB empty array: its size is its content.
            return Ok(());
        };
        guarded(path, || {
            let declared = ds.num_elements().map_err(|e| h5err(path, e))?;
            if Some(declared as usize) != crate::array::element_count(&info.shape) {
                return Err(corrupt(
                    path,
                    format!(
                        "variable '{}' holds {declared} values for size {:?}",
                        info.name, info.shape
                    ),
                ));
            }
            let n = declared as usize;
            if let Some(c) = *chunk
                && c > n.max(1 << 20)
            {
                return Err(corrupt(
                    path,
                    format!(
                        "variable '{}' ({} elements) is stored in chunks of {c} elements, \
                         larger than the dataset itself",
                        info.name, n
                    ),
                ));
            }
            let mut raw = vec![0u8; n.saturating_mul(el.size)];
            ds.read_raw_bytes_into(&mut raw)
                .map_err(|e| h5err(path, e))?;
            sink.take(&raw);
            Ok(())
        })
    }
}
