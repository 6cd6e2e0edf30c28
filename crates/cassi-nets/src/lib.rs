//! Pretrained deep networks of cassi, CPU inference in f32: the MST-S /
//! MST-L and HDNet reconstructors and the HSI-SDeCNN denoiser, loading the
//! official PyTorch checkpoints (`.pth` state dicts or `.safetensors`).
//!
//! * [`TensorMap`] reads a checkpoint; networks load it strictly (every
//!   parameter present with its shape, no tensor left over), and any
//!   mismatch is one [`NetError`] listing every bad tensor and the file.
//! * [`HsiSdecnnDenoiser`] plugs HSI-SDeCNN into cassi-core's PnP solvers
//!   as a [`cassi_core::Denoiser`].
//! * [`toolbox_inputs`] builds the networks' H and Phi from a measurement
//!   and mask the way the MST toolbox does.
//! * [`Reconstructor`] picks a network by name and maps a measurement and
//!   mask to a cube.
//! * Inputs and outputs are [`Tensor`]s in PyTorch's NCHW layout, so test
//!   vectors compare one to one.
//!
//! Heavy numerics (gemm, rayon) live in this crate only; the core build of
//! cassi does not depend on it.

pub mod checkpoint;
mod denoiser;
mod error;
mod fmap;
mod hdnet;
mod hsi_sdecnn;
mod inputs;
mod mst;
mod ops;
mod reconstructor;
mod tensor;

pub use checkpoint::{DType, StoredTensor, TensorMap, WeightLoader};
pub use denoiser::HsiSdecnnDenoiser;
pub use error::{NetError, Result};
pub use hdnet::HdNet;
pub use hsi_sdecnn::HsiSdecnn;
pub use inputs::toolbox_inputs;
pub use mst::{
    MST_BANDS, MST_MASK_WIDTH, MST_SIZE, Mst, MstActivations, MstConfig, MstMaskGuidance,
};
pub use reconstructor::{Reconstructor, TRAINED_STEP};
pub use tensor::Tensor;
