//! Science layer of cassi: data types, the CASSI optics model, metrics and
//! synthetic data. No file I/O and no printing happen here.
//!
//! Conventions (docs/CONVENTIONS.md, each pinned by a test): cubes are (bands, rows,
//! cols) f32 with band 0 the shortest wavelength; dispersion moves band k
//! toward larger column index; angles are degrees at every public boundary.

#![deny(clippy::undocumented_unsafe_blocks)]

pub mod calib;
pub mod color;
pub mod cube;
pub mod denoise;
pub mod error;
pub mod instrument;
pub mod limits;
pub mod linop;
pub mod metrics;
pub mod optics;
pub mod params;
pub mod recon;
pub mod rng;
mod scratch;
mod simd;
pub mod solvers;
pub mod stats;
pub mod synth;

pub use cube::{Cube, Frame, Mask, Measurement};
pub use denoise::Denoiser;
pub use error::{CassiError, Result};
pub use instrument::{Instrument, STANDARD_WAVELENGTHS_NM};
pub use linop::{
    AatNormaliser, LinearOperator, NonNegativeOperator, NormaliserKind, adjoint_mismatch,
    row_sum_majoriser,
};
pub use params::{DispersionParams, MaskPose, Mismatch, Parameter};
pub use rng::Rng;
pub use simd::kernel_copy;
