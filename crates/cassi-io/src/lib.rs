//! File formats for cassi: MATLAB `.mat` (v5, compressed or not, and v7.3),
//! NumPy `.npy`/`.npz`, PNG previews.
//!
//! * [`load_cube`], [`load_frame`], [`load_array`] read a variable, check its
//!   shape and that it is finite, and return core types (f32, row-major).
//! * [`save_cube`], [`save_frame`], [`save_array`] write `.npy`, `.npz` or
//!   `.mat` (v5, single precision) chosen by extension, atomically.
//! * [`describe`] lists what a file holds (`cassi info`).
//! * [`write_frame_png16`], [`write_band_pngs`], [`write_rgb_png`] write PNGs;
//!   [`write_atomic`] writes any bytes atomically.
//! * [`shared_data::for_test`] finds the public test data outside the
//!   repository (or fails the test when CI requires it).
//! * [`OutputSet`] checks a command's outputs against its inputs before any
//!   work and commits them together (all or none).
//!
//! Conventions: MATLAB data are column-major and v7.3 stores them in HDF5 with
//! the axes reversed; every reader here returns the shape the file's own tool
//! shows (MATLAB `size`, NumPy `shape`) with values in C order. Cubes are
//! (bands, rows, cols) in memory; `.mat` files store them as (rows, cols,
//! bands), `.npy`/`.npz` as (bands, rows, cols) (see [`load_cube`]).
//!
//! Every error is an [`IoError`] whose message starts with the file path.
//! No reader panics on malformed input, and every allocation is bounded by
//! the data actually present (a lying header cannot trigger a huge one).

#![forbid(unsafe_code)]

mod array;
mod atomic;
mod decode;
mod describe;
mod error;
mod escape;
mod load;
mod mat5;
mod mat73;
mod npy;
mod open;
mod output_set;
mod png;
pub mod shared_data;
mod temporaries;

pub use decode::Stats;
pub use describe::{FileSummary, VariableSummary, describe};
pub use error::{IoError, Result};
pub use escape::esc;
pub use load::{
    Array, CubeLayout, load_array, load_cube, load_frame, save_array, save_cube, save_frame,
};
pub use npy::numpy_shape;
pub use open::FileFormat;
pub use output_set::{CheckedSet, OutputSet, Staging, output_exists};
pub use png::{write_band_pngs, write_frame_png16, write_rgb_png};
pub use temporaries::{remove_stale_temporaries, remove_temporaries_for_exit};

/// Checks that `path` has an extension cassi can write (.npy, .npz, .mat),
/// so a command can refuse a bad output name before doing any work.
pub fn check_output_format(path: impl AsRef<std::path::Path>) -> Result<()> {
    open::extension(path.as_ref(), true).map(|_| ())
}

/// Writes `bytes` to `path` atomically (temporary file in the same directory,
/// flushed, then renamed): a crash leaves the old file or the new one, never
/// a partial one. For side files such as JSON records.
pub fn write_atomic(path: impl AsRef<std::path::Path>, bytes: &[u8]) -> Result<()> {
    atomic::write_bytes(path.as_ref(), bytes)
}
