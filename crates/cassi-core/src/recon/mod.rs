//! Reconstruction: a measurement and the assumed instrument ([`Model`]) in,
//! a cube out.
//!
//! * [`registry`] names every method (iterative, network, PnP with a
//!   learned denoiser), with its weights hint and shape rules.
//! * [`Method`] holds the iterative recipes (GAP-TV, ADMM-TV, PnP-TV).
//! * [`ModelProblem`] is what every model-based recipe starts from.
//! * [`Reconstructor`] is the interface every method implements (the
//!   learned ones in cassi-nets).

mod method;
mod model;
mod problem;
mod reconstructor;
pub mod registry;

pub use method::Method;
pub use model::Model;
pub use problem::{ModelProblem, Reconstruction, fit_width};
pub use reconstructor::Reconstructor;
pub use registry::{MethodId, MethodKind, MethodSpec};

use crate::cube::{Mask, Measurement};
use crate::error::Result;
use crate::optics::DispersionModel;
use crate::params::Mismatch;
use crate::solvers::Observer;

/// [`Method::solve`] with the instrument given piecewise. Kept only for the
/// calibration bench (`cassi-bench`'s `calibrate`), which is being reworked
/// elsewhere and adopts [`Model`] with calibration (issue 15); new callers
/// build a [`Model`]. The nominal stride, which iterative methods do not
/// use, is taken to be the model's a1.
pub fn reconstruct(
    measurement: &Measurement,
    nominal_mask: &Mask,
    bands: usize,
    model_params: &Mismatch,
    model: DispersionModel,
    method: &Method,
    observer: &mut dyn Observer,
) -> Result<problem::Reconstruction> {
    let model = Model::new(nominal_mask, bands, model_params.a1, *model_params, model)?;
    method.solve(measurement, &model, observer)
}

#[cfg(test)]
mod tests;
