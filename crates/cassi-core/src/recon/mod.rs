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

#[cfg(test)]
mod tests;
