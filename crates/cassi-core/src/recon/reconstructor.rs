//! One interface over every reconstruction method: the iterative recipes
//! here, PnP-HSICNN and the pretrained networks in cassi-nets. A caller
//! that holds a `dyn Reconstructor` runs any of them on the same
//! measurement and [`Model`].

use crate::cube::{Cube, Measurement};
use crate::error::Result;
use crate::solvers::Observer;

use super::method::Method;
use super::model::Model;

/// A reconstruction method, ready to run (settings chosen, weights loaded).
/// Each takes what it can of `model`: the iterative and PnP methods the
/// whole instrument, a network the mask pose only (it keeps its trained
/// dispersion). `&mut self`: a learned denoiser keeps buffers between calls.
pub trait Reconstructor {
    /// The method's registry name.
    fn name(&self) -> &str;

    /// The cube reconstructed from `y`, the instrument taken to be `model`;
    /// `observer` hears each iteration (methods without iterations call it
    /// never).
    fn reconstruct(
        &mut self,
        y: &Measurement,
        model: &Model,
        observer: &mut dyn Observer,
    ) -> Result<Cube>;
}

impl Reconstructor for Method {
    fn name(&self) -> &str {
        Method::name(self)
    }

    fn reconstruct(
        &mut self,
        y: &Measurement,
        model: &Model,
        observer: &mut dyn Observer,
    ) -> Result<Cube> {
        Ok(self.solve(y, model, observer)?.cube)
    }
}
