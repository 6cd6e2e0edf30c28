//! A pretrained reconstructor chosen by its registry id, from a measurement
//! and mask to a cube: what a command line or an evaluation calls.

use std::path::Path;

use cassi_core::recon::registry::{NETWORK_BANDS, NETWORK_STEP};
use cassi_core::recon::{MethodId, MethodKind, Model, Reconstructor};
use cassi_core::solvers::Observer;
use cassi_core::{Cube, Mask, MaskPose, Measurement};

use crate::error::{NetError, Result};
use crate::hdnet::HdNet;
use crate::inputs::{PosedInputs, posed_inputs};
use crate::mst::{Mst, MstConfig};
use crate::tensor::Tensor;

/// The pretrained networks, loaded.
pub enum Network {
    Mst { id: MethodId, net: Mst },
    HdNet(HdNet),
}

impl Network {
    /// Loads network `id` (a registry entry of kind
    /// [`MethodKind::Network`]) from a `.pth` state dict or `.safetensors`
    /// file, strictly.
    pub fn load(id: MethodId, weights: impl AsRef<Path>) -> Result<Self> {
        Ok(match id {
            MethodId::MstS => Self::Mst {
                id,
                net: Mst::load(weights, MstConfig::SMALL)?,
            },
            MethodId::MstL => Self::Mst {
                id,
                net: Mst::load(weights, MstConfig::LARGE)?,
            },
            MethodId::HdNet => Self::HdNet(HdNet::load(weights)?),
            MethodId::GapTv | MethodId::AdmmTv | MethodId::PnpTv | MethodId::PnpHsicnn => {
                return Err(NetError::Input {
                    what: "network".into(),
                    got: id.name().into(),
                    expected: format!(
                        "one of {}",
                        cassi_core::recon::registry::names_of(MethodKind::Network)
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                });
            }
        })
    }

    pub fn id(&self) -> MethodId {
        match self {
            Self::Mst { id, .. } => *id,
            Self::HdNet(_) => MethodId::HdNet,
        }
    }

    /// The cube (28 bands, rows, cols) from a measurement `y` (rows × cols
    /// plus 54 columns) and the coded aperture `nominal_mask` (rows × cols) placed at
    /// `pose` (identity: the nominal instrument; a calibration's or the true
    /// dx, dy, θ), with the toolbox's input convention
    /// ([`crate::posed_inputs`], trained step 2; a1 and α are not inputs of
    /// the networks). MST needs 256 × 256; HDNet does not use the mask.
    pub fn reconstruct(
        &self,
        y: &Measurement,
        nominal_mask: &Mask,
        pose: &MaskPose,
    ) -> Result<NetReconstruction> {
        let PosedInputs {
            h,
            phi,
            width_fitted,
        } = posed_inputs(y, nominal_mask, pose, NETWORK_BANDS, NETWORK_STEP)?;
        let out = match self {
            Self::Mst { net, .. } => net.forward(&h, &phi)?,
            Self::HdNet(net) => net.forward(&h)?,
        };
        Ok(NetReconstruction {
            cube: cube_of(out)?,
            width_fitted,
        })
    }
}

/// A network takes the model's nominal mask at the model's pose and keeps
/// its trained dispersion; it has no iterations to observe.
impl Reconstructor for Network {
    fn name(&self) -> &str {
        self.id().name()
    }

    fn reconstruct(
        &mut self,
        y: &Measurement,
        model: &Model,
        _observer: &mut dyn Observer,
    ) -> cassi_core::Result<Cube> {
        let pose = model.mismatch().pose();
        Ok(Network::reconstruct(self, y, model.nominal_mask(), &pose)?.cube)
    }
}

/// A network's cube and how the measurement was fitted to its input.
#[derive(Debug, Clone)]
pub struct NetReconstruction {
    pub cube: Cube,
    /// (measurement columns, network columns) when they differed.
    pub width_fitted: Option<(usize, usize)>,
}

/// A (1, L, rows, cols) tensor as a cube.
fn cube_of(t: Tensor) -> Result<Cube> {
    let [_, l, h, w] = t.nchw("network output", None)?;
    Cube::from_vec(l, h, w, t.into_data()).map_err(|e| NetError::Input {
        what: "network output".into(),
        got: e.to_string(),
        expected: "a cube".into(),
    })
}
