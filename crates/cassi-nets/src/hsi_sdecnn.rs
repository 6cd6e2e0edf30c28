//! HSI-SDeCNN (PnP-CASSI's spectral denoiser, Maffei et al.): 7 adjacent
//! bands plus a noise-level map in, the denoised centre band out.
//! Pad to even size → pixel-unshuffle 2 → append σ map → 15 convs 3×3
//! (ReLU between) → pixel-shuffle 2 → crop. No residual.

use std::path::Path;

use crate::checkpoint::{TensorMap, WeightLoader};
use crate::error::{NetError, Result, shape_str};
use crate::fmap::FeatureMap;
use crate::ops::activation::relu_in_place;
use crate::ops::conv::Conv2d;
use crate::ops::pixel_shuffle::{pixel_shuffle2, pixel_unshuffle2, replicate_pad_to_even};
use crate::tensor::Tensor;

pub struct HsiSdecnn {
    convs: Vec<Conv2d>,
}

impl HsiSdecnn {
    /// Bands in the input stack; the output is the middle one.
    pub const IN_BANDS: usize = 7;
    const FEATURES: usize = 128;
    const CONVS: usize = 15;

    /// Loads `HSI_SDeCNN(in_nc=7, out_nc=1, nc=128, nb=15)` weights (`model.0` … `model.28`).
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        Self::from_tensors(TensorMap::load(path)?)
    }

    pub fn from_tensors(map: TensorMap) -> Result<Self> {
        let mut w = WeightLoader::new("HSI-SDeCNN", map);
        let convs = (0..Self::CONVS)
            .map(|i| {
                let cin = if i == 0 {
                    4 * Self::IN_BANDS + 1
                } else {
                    Self::FEATURES
                };
                let cout = if i + 1 == Self::CONVS {
                    4
                } else {
                    Self::FEATURES
                };
                Conv2d::load(&mut w, &format!("model.{}", 2 * i), cin, cout, 3, true)
            })
            .collect();
        w.finish()?;
        Ok(Self { convs })
    }

    /// PyTorch's `model(x, sigma)`: x (B, 7, h, w), sigma (B, 1, 1, 1) →
    /// (B, 1, h, w).
    pub fn forward(&self, x: &Tensor, sigma: &Tensor) -> Result<Tensor> {
        let [b, c, h, w] = x.nchw("HSI-SDeCNN input", Some(Self::IN_BANDS))?;
        if sigma.numel() != b {
            return Err(NetError::Input {
                what: "HSI-SDeCNN sigma".into(),
                got: shape_str(sigma.shape()),
                expected: format!("one value per batch element ({b}, 1, 1, 1)"),
            });
        }
        let mut out = Vec::with_capacity(b * h * w);
        for i in 0..b {
            let xi = FeatureMap::from_vec(
                c,
                h,
                w,
                x.data()[i * c * h * w..(i + 1) * c * h * w].to_vec(),
            );
            out.extend_from_slice(&self.denoise_stack(&xi, sigma.data()[i]).data);
        }
        Tensor::new(vec![b, 1, h, w], out)
    }

    /// One sample: `stack` (7, h, w), noise std `sigma` on the data's scale
    /// → the denoised centre band (1, h, w).
    pub(crate) fn denoise_stack(&self, stack: &FeatureMap, sigma: f32) -> FeatureMap {
        assert_eq!(stack.c, Self::IN_BANDS, "HSI-SDeCNN band stack");
        let padded = replicate_pad_to_even(stack);
        let u = pixel_unshuffle2(&padded);
        let mut f = FeatureMap::for_overwrite(u.c + 1, u.h, u.w);
        let (image, sigma_map) = f.data.split_at_mut(u.data.len());
        image.copy_from_slice(&u.data);
        sigma_map.fill(sigma);
        for (i, conv) in self.convs.iter().enumerate() {
            f = conv.forward(&f);
            if i + 1 < self.convs.len() {
                relu_in_place(&mut f.data);
            }
        }
        let full = pixel_shuffle2(&f);
        if (full.h, full.w) == (stack.h, stack.w) {
            return full;
        }
        let mut out = FeatureMap::zeros(1, stack.h, stack.w);
        for y in 0..stack.h {
            out.data[y * stack.w..(y + 1) * stack.w]
                .copy_from_slice(&full.data[y * full.w..y * full.w + stack.w]);
        }
        out
    }
}
