//! Denoisers: the prior step of plug-and-play solvers. TV (2-D per band,
//! and spatio-spectral 3-D) now; learned denoisers plug in the same way.

/// A denoiser of hyperspectral cubes, used as the prior step of GAP / ADMM.
/// Holds its own scratch buffers (hence `&mut self`), so a solver loop
/// allocates nothing.
pub trait Denoiser: Send {
    /// Denoises `cube` in place. `strength` is the denoiser's regularisation
    /// knob (the TV weight λ for TV; the noise σ for a learned denoiser).
    fn denoise(&mut self, cube: &mut crate::Cube, strength: f32);

    /// A short name for reports ("tv-chambolle-2d").
    fn name(&self) -> String;
}

/// The prior that does nothing: a solver with it only enforces the data
/// (GAP reduces to repeated projection onto {A x = y}) — for convergence
/// tests and for least-squares reconstructions.
pub struct NoPrior;

impl Denoiser for NoPrior {
    fn denoise(&mut self, _: &mut crate::Cube, _: f32) {}

    fn name(&self) -> String {
        "none".into()
    }
}

pub mod tv;
pub mod tv3d;
pub use tv::{
    TvChambolle2d, TvChambolleParams, TvScratch2d, isotropic_tv_2d, isotropic_tv_3d,
    tv_chambolle_2d,
};
pub use tv3d::{TvChambolle3d, TvScratch3d, tv_chambolle_3d};
