//! HDNet (Hu et al., CVPR 2022) as `HDNet()` of caiyuanhao1998/MST:
//! head conv 28→64, a body of 16 ResBlocks, SDL attention, EFF, 15 more
//! ResBlocks and a conv (with a residual over the body), tail conv 64→28.
//! Works for any image size; no residual to the input.

mod eff;
mod sdl;

use std::path::Path;

use crate::checkpoint::{TensorMap, WeightLoader};
use crate::error::Result;
use crate::fmap::FeatureMap;
use crate::ops::activation::relu_in_place;
use crate::ops::conv::Conv2d;
use crate::tensor::Tensor;
use eff::Eff;
use sdl::SdlAttention;

const FEATURES: usize = 64;
const BANDS: usize = 28;
const RES_BLOCKS_BEFORE: usize = 16;
const RES_BLOCKS_AFTER: usize = 15;

/// conv 3×3, ReLU, conv 3×3, + input.
struct ResBlock {
    conv1: Conv2d,
    conv2: Conv2d,
}

impl ResBlock {
    fn load(w: &mut WeightLoader, name: &str) -> Self {
        Self {
            conv1: Conv2d::load(w, &format!("{name}.body.0"), FEATURES, FEATURES, 3, true),
            conv2: Conv2d::load(w, &format!("{name}.body.2"), FEATURES, FEATURES, 3, true),
        }
    }

    fn forward(&self, x: FeatureMap) -> FeatureMap {
        let mut t = self.conv1.forward(&x);
        relu_in_place(&mut t.data);
        let mut t = self.conv2.forward(&t);
        t.add_assign(&x);
        t
    }
}

enum BodyLayer {
    Res(ResBlock),
    Sdl(Box<SdlAttention>),
    Eff(Eff),
    Conv(Conv2d),
}

pub struct HdNet {
    head: Conv2d,
    body: Vec<BodyLayer>,
    tail: Conv2d,
}

impl HdNet {
    pub const BANDS: usize = BANDS;

    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        Self::from_tensors(TensorMap::load(path)?)
    }

    pub fn from_tensors(map: TensorMap) -> Result<Self> {
        let mut w = WeightLoader::new("HDNet", map);
        let head = Conv2d::load(&mut w, "head.0", BANDS, FEATURES, 3, true);
        let mut body = Vec::new();
        for _ in 0..RES_BLOCKS_BEFORE {
            body.push(BodyLayer::Res(ResBlock::load(
                &mut w,
                &format!("body.{}", body.len()),
            )));
        }
        body.push(BodyLayer::Sdl(Box::new(SdlAttention::load(
            &mut w,
            &format!("body.{}", body.len()),
            FEATURES,
        ))));
        body.push(BodyLayer::Eff(Eff::load(
            &mut w,
            &format!("body.{}", body.len()),
            FEATURES,
        )));
        for _ in 0..RES_BLOCKS_AFTER {
            body.push(BodyLayer::Res(ResBlock::load(
                &mut w,
                &format!("body.{}", body.len()),
            )));
        }
        let last = format!("body.{}", body.len());
        body.push(BodyLayer::Conv(Conv2d::load(
            &mut w, &last, FEATURES, FEATURES, 3, true,
        )));
        let tail = Conv2d::load(&mut w, "tail.0", FEATURES, BANDS, 3, true);
        w.finish()?;
        Ok(Self { head, body, tail })
    }

    /// PyTorch's `model(H)`: (B, 28, h, w) → (B, 28, h, w).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let [b, c, h, w] = x.nchw("HDNet input", Some(BANDS))?;
        let len = c * h * w;
        let mut out = Vec::with_capacity(x.numel());
        for i in 0..b {
            let xi = FeatureMap::from_slice(c, h, w, &x.data()[i * len..(i + 1) * len]);
            out.extend_from_slice(&self.forward_sample(&xi).data);
        }
        Tensor::new(x.shape().to_vec(), out)
    }

    fn forward_sample(&self, x: &FeatureMap) -> FeatureMap {
        let f = self.head.forward(x);
        let mut r = f.clone();
        for layer in &self.body {
            r = match layer {
                BodyLayer::Res(block) => block.forward(r),
                BodyLayer::Sdl(sdl) => sdl.forward(&r),
                BodyLayer::Eff(eff) => eff.forward(&r),
                BodyLayer::Conv(conv) => conv.forward(&r),
            };
        }
        r.add_assign(&f);
        self.tail.forward(&r)
    }
}
