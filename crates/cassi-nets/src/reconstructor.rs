//! A pretrained reconstructor chosen by name, from a measurement and mask
//! to a cube: what a command line or an evaluation calls.

use std::path::Path;

use cassi_core::{Cube, Mask, MaskPose, Measurement};

use crate::error::{NetError, Result};
use crate::hdnet::HdNet;
use crate::inputs::{PosedInputs, posed_inputs};
use crate::mst::{MST_BANDS, Mst, MstConfig};
use crate::tensor::Tensor;

/// Dispersion step (detector columns per band) the networks were trained with.
pub const TRAINED_STEP: usize = 2;

pub enum Reconstructor {
    Mst(Mst),
    HdNet(HdNet),
}

impl Reconstructor {
    /// The names [`load`](Self::load) accepts.
    pub const NAMES: [&'static str; 3] = ["mst-s", "mst-l", "hdnet"];

    /// Loads network `name` (one of [`NAMES`](Self::NAMES)) from a `.pth`
    /// state dict or `.safetensors` file, strictly.
    pub fn load(name: &str, weights: impl AsRef<Path>) -> Result<Self> {
        Ok(match name {
            "mst-s" => Self::Mst(Mst::load(weights, MstConfig::SMALL)?),
            "mst-l" => Self::Mst(Mst::load(weights, MstConfig::LARGE)?),
            "hdnet" => Self::HdNet(HdNet::load(weights)?),
            other => {
                return Err(NetError::Input {
                    what: "network name".into(),
                    got: other.into(),
                    expected: format!("one of {}", Self::NAMES.join(", ")),
                });
            }
        })
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
        } = posed_inputs(y, nominal_mask, pose, MST_BANDS, TRAINED_STEP)?;
        let out = match self {
            Self::Mst(net) => net.forward(&h, &phi)?,
            Self::HdNet(net) => net.forward(&h)?,
        };
        Ok(NetReconstruction {
            cube: cube_of(out)?,
            width_fitted,
        })
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
