//! MST (Cai et al., CVPR 2022), the mask-guided spectral-wise transformer,
//! as `MST(dim=28, stage=2, num_blocks)` of caiyuanhao1998/MST: MST-S has
//! blocks [2, 2, 2], MST-L [4, 7, 5]. A U-net of MSABs; the inputs are the
//! shifted-back measurement H (B, 28, 256, 256) and the shifted 3-D mask
//! Phi (B, 28, 256, 310); out = mapping(features) + H.

mod mask_guide;
mod ms_msa;
mod msab;

use std::path::Path;

use crate::checkpoint::{TensorMap, WeightLoader};
use crate::error::{NetError, Result, shape_str};
use crate::fmap::FeatureMap;
use crate::ops::activation::leaky_relu_in_place;
use crate::ops::conv::Conv2d;
use crate::ops::conv_transpose::ConvTranspose2x2;
use crate::tensor::Tensor;
use msab::Msab;

/// Bands, and the image size the mask shift-back is built for.
pub const MST_BANDS: usize = 28;
pub const MST_SIZE: usize = 256;
/// Width of the shifted mask Phi: 256 + 2·27 (dispersion step 2).
pub const MST_MASK_WIDTH: usize = MST_SIZE + 2 * (MST_BANDS - 1);

/// Which MST: the block counts of encoder stages 0, 1 and the bottleneck
/// (the decoder mirrors the encoder).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MstConfig {
    pub num_blocks: [usize; 3],
}

impl MstConfig {
    pub const SMALL: MstConfig = MstConfig {
        num_blocks: [2, 2, 2],
    };
    pub const LARGE: MstConfig = MstConfig {
        num_blocks: [4, 7, 5],
    };

    fn name(&self) -> String {
        match *self {
            Self::SMALL => "MST-S".into(),
            Self::LARGE => "MST-L".into(),
            c => format!("MST{:?}", c.num_blocks),
        }
    }
}

struct EncoderStage {
    msab: Msab,
    fea_down: Conv2d,
    mask_down: Conv2d,
}

struct DecoderStage {
    up: ConvTranspose2x2,
    fusion: Conv2d,
    msab: Msab,
}

pub struct Mst {
    config: MstConfig,
    embedding: Conv2d,
    encoder: Vec<EncoderStage>,
    bottleneck: Msab,
    decoder: Vec<DecoderStage>,
    mapping: Conv2d,
}

/// Intermediate activations of batch element 0, each (1, C, h, w), for
/// checking against PyTorch.
pub struct MstActivations {
    /// After the embedding conv and LeakyReLU (1, 28, 256, 256).
    pub embedding: Tensor,
    /// `encoder_layers.0.0.blocks.0.0.mm` output, after shift-back (1, 28, 256, 256).
    pub enc0_block0_mask_attn: Tensor,
    /// Encoder stage-0 MSAB output = skip 0 (1, 28, 256, 256).
    pub enc0_msab: Tensor,
    /// Bottleneck MSAB output (1, 112, 64, 64).
    pub bottleneck: Tensor,
    /// `mapping` conv output before the residual (1, 28, 256, 256).
    pub mapping: Tensor,
}

impl Mst {
    pub fn load(path: impl AsRef<Path>, config: MstConfig) -> Result<Self> {
        Self::from_tensors(TensorMap::load(path)?, config)
    }

    pub fn from_tensors(map: TensorMap, config: MstConfig) -> Result<Self> {
        let mut w = WeightLoader::new(config.name(), map);
        let c0 = MST_BANDS;
        let embedding = Conv2d::load(&mut w, "embedding", c0, c0, 3, false);
        let encoder = (0..2)
            .map(|i| {
                let c = c0 << i;
                let p = format!("encoder_layers.{i}");
                EncoderStage {
                    msab: Msab::load(&mut w, &format!("{p}.0"), c, config.num_blocks[i]),
                    fea_down: Conv2d::load_strided(&mut w, &format!("{p}.1"), c, 2 * c, 4, 2, 1),
                    mask_down: Conv2d::load_strided(&mut w, &format!("{p}.2"), c, 2 * c, 4, 2, 1),
                }
            })
            .collect();
        let bottleneck = Msab::load(&mut w, "bottleneck", 4 * c0, config.num_blocks[2]);
        let decoder = (0..2)
            .map(|i| {
                let c = (4 * c0) >> i;
                let p = format!("decoder_layers.{i}");
                DecoderStage {
                    up: ConvTranspose2x2::load(&mut w, &format!("{p}.0"), c, c / 2),
                    fusion: Conv2d::load(&mut w, &format!("{p}.1"), c, c / 2, 1, false),
                    msab: Msab::load(&mut w, &format!("{p}.2"), c / 2, config.num_blocks[1 - i]),
                }
            })
            .collect();
        let mapping = Conv2d::load(&mut w, "mapping", c0, c0, 3, false);
        w.finish()?;
        Ok(Self {
            config,
            embedding,
            encoder,
            bottleneck,
            decoder,
            mapping,
        })
    }

    pub fn config(&self) -> MstConfig {
        self.config
    }

    /// PyTorch's `model(H, Phi)`: H (B, 28, 256, 256), Phi (B, 28, 256, 310)
    /// → (B, 28, 256, 256). As in the reference, only Phi's first batch
    /// element guides the attention (it is one instrument's mask).
    pub fn forward(&self, h: &Tensor, phi: &Tensor) -> Result<Tensor> {
        let [b, ..] = self.check_inputs(h, phi)?;
        let mask = sample(phi, 0);
        let mut out = Vec::with_capacity(h.numel());
        for i in 0..b {
            out.extend(self.forward_sample(sample(h, i), &mask, false).0.data);
        }
        Tensor::new(h.shape().to_vec(), out)
    }

    /// [`forward`](Self::forward) of batch element 0 (1, 28, 256, 256), also
    /// returning the intermediate activations that the reference dumps.
    pub fn forward_with_activations(
        &self,
        h: &Tensor,
        phi: &Tensor,
    ) -> Result<(Tensor, MstActivations)> {
        self.check_inputs(h, phi)?;
        match self.forward_sample(sample(h, 0), &sample(phi, 0), true) {
            (out, Some(acts)) => Ok((batch_of_one(out), acts)),
            (_, None) => unreachable!("activations are recorded when asked for"),
        }
    }

    fn check_inputs(&self, h: &Tensor, phi: &Tensor) -> Result<[usize; 4]> {
        let dims = h.nchw("MST input H", Some(MST_BANDS))?;
        if dims[2..] != [MST_SIZE, MST_SIZE] {
            return Err(NetError::Input {
                what: "MST input H".into(),
                got: shape_str(h.shape()),
                expected: format!(
                    "(batch, {MST_BANDS}, {MST_SIZE}, {MST_SIZE}); MST's mask shift-back is built for 256×256"
                ),
            });
        }
        let want = [dims[0], MST_BANDS, MST_SIZE, MST_MASK_WIDTH];
        if phi.shape() != want {
            return Err(NetError::Input {
                what: "MST mask Phi".into(),
                got: shape_str(phi.shape()),
                expected: shape_str(&want),
            });
        }
        Ok(dims)
    }

    /// One sample; with `record`, also the activations the reference dumps.
    fn forward_sample(
        &self,
        x: FeatureMap,
        mask: &FeatureMap,
        record: bool,
    ) -> (FeatureMap, Option<MstActivations>) {
        let mut fea = self.embedding.forward(&x);
        leaky_relu_in_place(&mut fea.data, 0.1);
        let embedding = record.then(|| fea.clone());

        let mut skips = Vec::with_capacity(2);
        let mut masks = vec![mask.clone()];
        for (i, stage) in self.encoder.iter().enumerate() {
            fea = stage.msab.forward(fea, &masks[i]);
            skips.push(fea.clone());
            fea = stage.fea_down.forward(&fea);
            let down = stage.mask_down.forward(&masks[i]);
            masks.push(down);
        }
        fea = self.bottleneck.forward(fea, &masks[2]);
        let bottleneck = record.then(|| fea.clone());
        for (i, stage) in self.decoder.iter().enumerate() {
            let up = stage.up.forward(&fea);
            fea = stage.fusion.forward(&up.concat_channels(&skips[1 - i]));
            fea = stage.msab.forward(fea, &masks[1 - i]);
        }
        let mut out = self.mapping.forward(&fea);
        let acts = match (record, embedding, bottleneck) {
            (true, Some(embedding), Some(bottleneck)) => Some(MstActivations {
                embedding: batch_of_one(embedding),
                enc0_block0_mask_attn: batch_of_one(self.encoder[0].msab.mask_embedding(0, mask)),
                enc0_msab: batch_of_one(skips.swap_remove(0)),
                bottleneck: batch_of_one(bottleneck),
                mapping: batch_of_one(out.clone()),
            }),
            _ => None,
        };
        out.add_assign(&x);
        (out, acts)
    }
}

/// A feature map as a batch of one, (1, C, h, w).
fn batch_of_one(f: FeatureMap) -> Tensor {
    let shape = vec![1, f.c, f.h, f.w];
    Tensor::new(shape, f.data).expect("a feature map's data fits its shape")
}

/// Batch element `i` of an NCHW tensor as a feature map.
fn sample(t: &Tensor, i: usize) -> FeatureMap {
    let s = t.shape();
    let len = s[1] * s[2] * s[3];
    FeatureMap::from_vec(s[1], s[2], s[3], t.data()[i * len..(i + 1) * len].to_vec())
}
