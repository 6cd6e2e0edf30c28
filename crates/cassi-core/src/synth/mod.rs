//! Embedded synthetic data: procedural scenes and random masks, so the
//! toolkit runs (demo, tests, benchmarks) with no data files.
//!
//! * [`synthetic_scene`] — a table-top hyperspectral scene with objects, a
//!   colour chart, multi-scale texture and smooth, region-specific spectra.
//! * [`random_binary_mask`] — an i.i.d. Bernoulli coded aperture.
//! * [`spectra`] — the reflectance families and blackbody illuminants the
//!   scene is built from.

mod mask;
mod noise;
mod scene;
pub mod spectra;

pub use mask::random_binary_mask;
#[cfg(test)]
pub(crate) use mask::uniform_grey_mask;
pub use scene::{SceneSpec, synthetic_scene};
