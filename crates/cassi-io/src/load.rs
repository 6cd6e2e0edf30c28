//! High-level loaders and savers for cubes, frames and plain arrays.

use std::path::Path;

use cassi_core::{Cube, Frame};

use crate::array::shape_str;
use crate::atomic;
use crate::error::{IoError, Result};
use crate::open::{Ext, FileFormat, Opened, extension};

/// How the three axes of a stored cube map to (bands, rows, cols).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CubeLayout {
    /// Decide from the format and the shape; see [`load_cube`].
    #[default]
    Auto,
    /// Stored as (bands, rows, cols): the NumPy/PyTorch convention.
    BandsRowsCols,
    /// Stored as (rows, cols, bands): the MATLAB benchmark convention.
    RowsColsBands,
}

/// A numeric variable read from a file: its shape as the file shows it and its
/// values as f32 in row-major (C) order, checked finite.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    pub name: String,
    pub shape: Vec<usize>,
    /// The element type in the file (e.g. "double", "uint8", "float32").
    pub dtype: String,
    pub data: Vec<f32>,
}

fn read_array(path: &Path, var: Option<&str>) -> Result<(Array, FileFormat)> {
    let mut file = Opened::open(path)?;
    let (i, info) = file.select(path, var)?;
    let data = file.read_f32(path, i, &info)?;
    Ok((
        Array {
            name: info.name,
            shape: info.shape,
            dtype: info.dtype,
            data,
        },
        file.format(),
    ))
}

/// Loads a numeric variable of any shape (`.mat`, `.npy`, `.npz`) as f32 in
/// C order with the shape the file shows. `var` picks it by name; with `None`
/// the file must hold exactly one numeric variable. A `.npy` holds one array,
/// which any name selects. Errors on NaN/±Inf.
pub fn load_array(path: impl AsRef<Path>, var: Option<&str>) -> Result<Array> {
    read_array(path.as_ref(), var).map(|(a, _)| a)
}

/// Whether axis length `x` is "clearly spectral" next to `y` and `z`: at most
/// half of each.
fn clearly_small(x: usize, y: usize, z: usize) -> bool {
    x.saturating_mul(2) <= y && x.saturating_mul(2) <= z
}

/// The [`CubeLayout::Auto`] rule (see [`load_cube`]) for stored shape
/// (a, b, c); `None` when ambiguous.
fn auto_layout(a: usize, b: usize, c: usize, is_mat: bool) -> Option<CubeLayout> {
    match (clearly_small(a, b, c), clearly_small(c, a, b)) {
        (true, false) => Some(CubeLayout::BandsRowsCols),
        (false, true) => Some(CubeLayout::RowsColsBands),
        _ if a.saturating_mul(2) <= b && c.saturating_mul(2) <= b => None,
        _ if is_mat => Some(CubeLayout::RowsColsBands),
        _ => Some(CubeLayout::BandsRowsCols),
    }
}

/// Loads a hyperspectral cube as (bands, rows, cols).
///
/// The variable must be 3-D (a 4-D+ array is accepted when dropping its
/// singleton axes leaves 3, e.g. a PyTorch (1, 28, 256, 256)).
///
/// With [`CubeLayout::Auto`], for a stored shape (a, b, c) an end axis is
/// *clearly spectral* when it is at most half of each of the other two axes
/// (e.g. 28 next to 256×256):
/// * if exactly one end axis is clearly spectral, it is the band axis (first →
///   (bands, rows, cols), last → (rows, cols, bands)), whatever the format;
/// * if neither is, but both end axes are at most half the middle one (e.g.
///   3×64×3, 28×256×31), the layout is ambiguous and the load fails, asking for
///   an explicit layout (`--layout`);
/// * otherwise the format's convention applies: `.mat` files are
///   (rows, cols, bands) (the MATLAB benchmark convention), `.npy`/`.npz`
///   files (bands, rows, cols) (the NumPy convention).
///
/// Errors name the file and variable: wrong number of dimensions (with the
/// shape got and wanted), NaN/±Inf (with the index), unknown variable (with the
/// variables present).
pub fn load_cube(path: impl AsRef<Path>, var: Option<&str>, layout: CubeLayout) -> Result<Cube> {
    let path = path.as_ref();
    let (arr, format) = read_array(path, var)?;
    let mut shape = arr.shape.clone();
    if shape.len() > 3 {
        shape.retain(|&d| d != 1);
    }
    let [a, b, c] = shape[..] else {
        return Err(IoError::Shape {
            path: path.to_path_buf(),
            name: arr.name,
            got: shape_str(&arr.shape),
            expected: "a 3-D cube: (bands, rows, cols) or (rows, cols, bands)".into(),
        });
    };
    let layout = match layout {
        CubeLayout::Auto => {
            let is_mat = matches!(format, FileFormat::MatV5 | FileFormat::MatV73);
            auto_layout(a, b, c, is_mat).ok_or_else(|| IoError::AmbiguousLayout {
                path: path.to_path_buf(),
                name: arr.name.clone(),
                shape: shape_str(&arr.shape),
            })?
        }
        l => l,
    };
    let cube = match layout {
        CubeLayout::RowsColsBands => {
            // (rows, cols, bands) → (bands, rows, cols)
            let (rows, cols, bands) = (a, b, c);
            let mut out = vec![0f32; arr.data.len()];
            for (p, px) in arr.data.chunks_exact(bands.max(1)).enumerate() {
                for (k, &v) in px.iter().enumerate() {
                    out[k * rows * cols + p] = v;
                }
            }
            Cube::from_vec(bands, rows, cols, out)
        }
        _ => Cube::from_vec(a, b, c, arr.data),
    };
    cube.map_err(|e| IoError::core(path, e))
}

/// Loads a 2-D frame (mask, measurement) as (rows, cols). A 3-D (or higher)
/// array is accepted when dropping singleton axes leaves two, e.g. (1, H, W)
/// or (H, W, 1). See [`load_array`] for `var`.
pub fn load_frame(path: impl AsRef<Path>, var: Option<&str>) -> Result<Frame> {
    let path = path.as_ref();
    let (arr, _) = read_array(path, var)?;
    let mut shape = arr.shape.clone();
    if shape.len() > 2 {
        shape.retain(|&d| d != 1);
    }
    let [rows, cols] = shape[..] else {
        return Err(IoError::Shape {
            path: path.to_path_buf(),
            name: arr.name,
            got: shape_str(&arr.shape),
            expected: "a 2-D frame (rows, cols), or 3-D with one singleton axis".into(),
        });
    };
    Frame::from_vec(rows, cols, arr.data).map_err(|e| IoError::core(path, e))
}

/// Saves f32 data of `shape` (C order) under `name`, format by extension:
/// `.npy` (the name is not stored), `.npz` (member `name`), `.mat` (MAT v5,
/// single precision, variable `name`, same shape).
pub fn save_array(path: impl AsRef<Path>, name: &str, shape: &[usize], data: &[f32]) -> Result<()> {
    let path = path.as_ref();
    if crate::array::element_count(shape) != Some(data.len()) {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: format!(
                "{} values do not fill shape {}",
                data.len(),
                shape_str(shape)
            ),
        });
    }
    match extension(path, true)? {
        Ext::Npy => atomic::write_bytes(path, &crate::npy::encode_f32(shape, data)),
        Ext::Npz => {
            if name.is_empty() || name.contains('/') {
                return Err(IoError::InvalidArgument {
                    path: path.to_path_buf(),
                    reason: format!("'{name}' is not a usable .npz array name"),
                });
            }
            let npy = crate::npy::encode_f32(shape, data);
            atomic::write_with(path, |w| crate::npy::write_npz(w, name, &npy))
        }
        Ext::Mat => {
            let bytes = crate::mat5::encode_single(path, name, shape, data)?;
            atomic::write_bytes(path, &bytes)
        }
    }
}

/// Saves a cube. `.npy`/`.npz` store (bands, rows, cols), the NumPy
/// convention; `.mat` stores (rows, cols, bands) single precision, the MATLAB
/// benchmark convention, as variable `name`. So [`load_cube`] with
/// [`CubeLayout::Auto`] reads back what this writes, for every band count
/// that is not ambiguous. The write is atomic.
pub fn save_cube(path: impl AsRef<Path>, cube: &Cube, name: &str) -> Result<()> {
    let path = path.as_ref();
    let (bands, rows, cols) = cube.shape();
    match extension(path, true)? {
        Ext::Mat => {
            // (bands, rows, cols) → (rows, cols, bands)
            let src = cube.as_slice();
            let n = rows * cols;
            let mut out = vec![0f32; src.len()];
            for k in 0..bands {
                for p in 0..n {
                    out[p * bands + k] = src[k * n + p];
                }
            }
            save_array(path, name, &[rows, cols, bands], &out)
        }
        _ => save_array(path, name, &[bands, rows, cols], cube.as_slice()),
    }
}

/// Saves a frame as (rows, cols) in any of the three formats (see
/// [`save_array`]). The write is atomic.
pub fn save_frame(path: impl AsRef<Path>, frame: &Frame, name: &str) -> Result<()> {
    let (rows, cols) = frame.shape();
    save_array(path, name, &[rows, cols], frame.as_slice())
}

#[cfg(test)]
mod tests {
    use super::*;
    use CubeLayout::{BandsRowsCols as Brc, RowsColsBands as Rcb};

    #[test]
    fn auto_layout_rule() {
        for (shape, mat, npy) in [
            // Benchmark cubes in either order, in either format.
            ((256, 256, 28), Some(Rcb), Some(Rcb)),
            ((28, 256, 256), Some(Brc), Some(Brc)),
            ((512, 256, 31), Some(Rcb), Some(Rcb)),
            ((28, 512, 256), Some(Brc), Some(Brc)),
            // No clear spectral axis: the format's convention.
            ((4, 5, 3), Some(Rcb), Some(Brc)),
            ((28, 6, 7), Some(Rcb), Some(Brc)),
            ((64, 64, 64), Some(Rcb), Some(Brc)),
            // Both end axes small next to the middle one: ambiguous.
            ((3, 8, 3), None, None),
            ((28, 256, 31), None, None),
            // Single-band cubes.
            ((3, 4, 1), Some(Rcb), Some(Rcb)),
            ((1, 3, 4), Some(Brc), Some(Brc)),
        ] {
            let (a, b, c) = shape;
            assert_eq!(auto_layout(a, b, c, true), mat, ".mat {shape:?}");
            assert_eq!(auto_layout(a, b, c, false), npy, ".npy {shape:?}");
        }
    }
}
