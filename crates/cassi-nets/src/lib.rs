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
//!   and mask the way the MST toolbox does; [`posed_inputs`] does it with
//!   the mask moved to a calibrated (or true) pose.
//! * [`PnpHsicnn`] is plug-and-play GAP with a TV warm-up then scheduled
//!   HSI-SDeCNN / TV steps (the paper's PnP-HSICNN), on the nominal or a
//!   calibrated instrument model.
//! * [`Network`] is a pretrained reconstructor chosen by its registry id
//!   ([`cassi_core::recon::MethodId`]); it and [`PnpHsicnn`] implement
//!   [`cassi_core::recon::Reconstructor`].
//! * Inputs and outputs are [`Tensor`]s in PyTorch's NCHW layout, so test
//!   vectors compare one to one.
//!
//! Heavy numerics (gemm, rayon) live in this crate only; the core build of
//! cassi does not depend on it.

#![deny(clippy::undocumented_unsafe_blocks)]

mod buffer_pool;
pub mod checkpoint;
mod denoiser;
mod error;
mod fmap;
mod hdnet;
mod hsi_sdecnn;
mod inputs;
mod mst;
mod network;
mod ops;
mod pnp;
mod tensor;

pub use buffer_pool::{MAX_POOLED_BYTES, cached_buffer_bytes, release_cached_buffers};
pub use checkpoint::{DType, StoredTensor, TensorMap, WeightLoader};
pub use denoiser::HsiSdecnnDenoiser;
pub use error::{NetError, Result};
pub use hdnet::HdNet;
pub use hsi_sdecnn::HsiSdecnn;
pub use inputs::{PosedInputs, posed_inputs, toolbox_inputs};
pub use mst::{
    MST_MASK_WIDTH, MST_SIZE, Mst, MstActivations, MstConfig, MstMaskGuidance, NETWORK_BANDS,
};
pub use network::{NetReconstruction, Network};
pub use pnp::{
    DenoiserSchedule, PnpHsicnn, PnpHsicnnParams, PnpReconstruction, ScheduledDenoiser, Stage,
};
pub use tensor::Tensor;
