//! The learned methods (MST-S/L, HDNet, PnP-HSICNN) from Python, in a
//! package built with the `nets` feature (`MATURIN_PEP517_ARGS="--features
//! nets" pip install ./python`); without it, a clear error saying so.

use std::path::{Path, PathBuf};

use pyo3::prelude::*;

use cassi_core::recon::{MethodId, Model};
use cassi_core::{Cube, Measurement};

use crate::errors::{Kind, raise, value_error};

/// Whether this package can run the learned methods.
pub const BUILT: bool = cfg!(feature = "nets");

/// An error when this package cannot run the learned method `id`.
pub fn require_nets(py: Python<'_>, id: MethodId) -> PyResult<()> {
    if BUILT {
        return Ok(());
    }
    Err(value_error(
        py,
        format!(
            "method {id} is a learned method, and this cassi package was built without the deep \
             networks; reinstall it with them: \
             MATURIN_PEP517_ARGS=\"--features nets\" pip install ./python"
        ),
    ))
}

/// `weights` for `id`, checked to exist; the error names where the official
/// weights come from.
pub fn weights_for(py: Python<'_>, id: MethodId, weights: Option<PathBuf>) -> PyResult<PathBuf> {
    require_nets(py, id)?;
    let official = id.spec().weights.map_or("its checkpoint", |w| w.official);
    let Some(path) = weights else {
        return Err(value_error(
            py,
            format!("method {id} needs weights=PATH (.pth or .safetensors; {official})"),
        ));
    };
    if !path.is_file() {
        return Err(raise(
            py,
            Kind::NotFound,
            format!("weights {}: no such file ({official})", path.display()),
        ));
    }
    Ok(path)
}

/// The cube from `y` by the learned method `id` with `weights`, the
/// instrument taken to be `model` (a network uses its mask pose only);
/// `iterations` and `strength` tune PnP-HSICNN (its iteration count and TV
/// weight).
#[cfg(feature = "nets")]
pub fn reconstruct(
    id: MethodId,
    weights: &Path,
    y: &Measurement,
    model: &Model,
    iterations: Option<usize>,
    strength: Option<f32>,
    observer: &mut dyn cassi_core::solvers::Observer,
) -> cassi_core::Result<Cube> {
    use cassi_core::CassiError;
    use cassi_core::recon::{MethodKind, Reconstructor};
    use cassi_nets::{Network, PnpHsicnn, PnpHsicnnParams};
    let mut method: Box<dyn Reconstructor> = match id.kind() {
        MethodKind::LearnedPnp => Box::new(
            PnpHsicnn::load(
                weights,
                PnpHsicnnParams::default().with_overrides(iterations, strength),
            )
            .map_err(CassiError::from)?,
        ),
        _ => Box::new(Network::load(id, weights).map_err(CassiError::from)?),
    };
    method.reconstruct(y, model, observer)
}

#[cfg(not(feature = "nets"))]
pub fn reconstruct(
    id: MethodId,
    _weights: &Path,
    _y: &Measurement,
    _model: &Model,
    _iterations: Option<usize>,
    _strength: Option<f32>,
    _observer: &mut dyn cassi_core::solvers::Observer,
) -> cassi_core::Result<Cube> {
    // weights_for refuses every learned method first in this build
    Err(cassi_core::CassiError::Meaningless {
        what: format!("method {id}"),
        reason: "this package was built without the deep networks".into(),
    })
}
