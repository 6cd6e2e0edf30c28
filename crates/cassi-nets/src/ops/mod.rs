//! The layers the networks are built from, on single-sample channel-first
//! feature maps. Parallelism (rayon) lives here, not in the networks.

pub(crate) mod activation;
pub(crate) mod conv;
pub(crate) mod conv_transpose;
pub(crate) mod depthwise;
pub(crate) mod matmul;
pub(crate) mod norm;
pub(crate) mod pixel_shuffle;
pub(crate) mod pointwise;
pub(crate) mod pool;
pub(crate) mod simd;
pub(crate) mod winograd;
