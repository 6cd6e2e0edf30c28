//! PnP-HSICNN (Zheng et al. 2021, PnP-CASSI; the reference paper §5.1):
//! cassi-core's accelerated GAP with a denoiser that follows a schedule —
//! Chambolle TV for a warm-up, then cycles of the HSI-SDeCNN network and
//! TV.
//!
//! * [`DenoiserSchedule`] says which denoiser each iteration uses (a value
//!   to inspect and test, not a branch buried in a loop).
//! * [`ScheduledDenoiser`] is the [`cassi_core::Denoiser`] that follows it.
//! * [`PnpHsicnn`] is the recipe: the HSI-SDeCNN weights plus
//!   [`PnpHsicnnParams`], run on a [`cassi_core::recon::ModelProblem`] so it
//!   takes the nominal or a calibrated instrument like the TV solvers.

mod recipe;
mod schedule;
mod scheduled_denoiser;

pub use recipe::{PnpHsicnn, PnpHsicnnParams, PnpReconstruction};
pub use schedule::{DenoiserSchedule, Stage};
pub use scheduled_denoiser::ScheduledDenoiser;
