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

use cassi_core::recon::registry::NETWORK_STEP;
/// Bands, and the image size the mask shift-back is built for: the
/// registry's, where every method's shape rules live.
pub use cassi_core::recon::registry::{MST_SIZE, NETWORK_BANDS};
/// Width of the shifted mask Phi: 256 + 2·27 (dispersion step 2).
pub const MST_MASK_WIDTH: usize = MST_SIZE + NETWORK_STEP * (NETWORK_BANDS - 1);

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
    /// Tells this network's [`MstMaskGuidance`] from another's.
    id: u64,
    config: MstConfig,
    embedding: Conv2d,
    encoder: Vec<EncoderStage>,
    bottleneck: Msab,
    decoder: Vec<DecoderStage>,
    mapping: Conv2d,
}

static NEXT_MST_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// The mask-dependent half of an MST forward: every block's mask embedding
/// (the mask-guided mechanism after shift-back, at each level), which does
/// not depend on the measurement. Compute it once per coded aperture with
/// [`Mst::mask_guidance`] and reuse it for any number of measurements.
pub struct MstMaskGuidance {
    net_id: u64,
    /// Per MSAB in forward order (encoder 0, encoder 1, bottleneck,
    /// decoder 0, decoder 1), one embedding per block.
    per_msab: [Vec<FeatureMap>; 5],
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
        let c0 = NETWORK_BANDS;
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
            id: NEXT_MST_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
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

    /// PyTorch's `model(H, Phi)`: H (B, 28, 256, 256), Phi (B′, 28, 256, 310)
    /// → (B, 28, 256, 256). As in the reference, only Phi's first batch
    /// element guides the attention (it is one instrument's mask).
    pub fn forward(&self, h: &Tensor, phi: &Tensor) -> Result<Tensor> {
        self.check_h(h)?;
        self.forward_guided(h, &self.mask_guidance(phi)?)
    }

    /// The mask-dependent half of [`forward`](Self::forward), from Phi's
    /// first batch element.
    pub fn mask_guidance(&self, phi: &Tensor) -> Result<MstMaskGuidance> {
        let dims = phi.nchw("MST mask Phi", Some(NETWORK_BANDS))?;
        if dims[2..] != [MST_SIZE, MST_MASK_WIDTH] {
            return Err(NetError::Input {
                what: "MST mask Phi".into(),
                got: shape_str(phi.shape()),
                expected: format!("(batch, {NETWORK_BANDS}, {MST_SIZE}, {MST_MASK_WIDTH})"),
            });
        }
        let m0 = sample(phi, 0);
        let m1 = self.encoder[0].mask_down.forward(&m0);
        let m2 = self.encoder[1].mask_down.forward(&m1);
        Ok(MstMaskGuidance {
            net_id: self.id,
            per_msab: [
                self.encoder[0].msab.mask_embeddings(&m0),
                self.encoder[1].msab.mask_embeddings(&m1),
                self.bottleneck.mask_embeddings(&m2),
                self.decoder[0].msab.mask_embeddings(&m1),
                self.decoder[1].msab.mask_embeddings(&m0),
            ],
        })
    }

    /// [`forward`](Self::forward) with the mask half precomputed by this
    /// network's [`mask_guidance`](Self::mask_guidance).
    pub fn forward_guided(&self, h: &Tensor, guidance: &MstMaskGuidance) -> Result<Tensor> {
        let [b, ..] = self.check_h(h)?;
        self.check_guidance(guidance)?;
        let mut out = Vec::with_capacity(h.numel());
        for i in 0..b {
            out.extend_from_slice(&self.forward_sample(sample(h, i), guidance, false).0.data);
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
        self.check_h(h)?;
        let guidance = self.mask_guidance(phi)?;
        match self.forward_sample(sample(h, 0), &guidance, true) {
            (out, Some(acts)) => Ok((batch_of_one(out), acts)),
            (_, None) => unreachable!("activations are recorded when asked for"),
        }
    }

    fn check_h(&self, h: &Tensor) -> Result<[usize; 4]> {
        let dims = h.nchw("MST input H", Some(NETWORK_BANDS))?;
        if dims[2..] != [MST_SIZE, MST_SIZE] {
            return Err(NetError::Input {
                what: "MST input H".into(),
                got: shape_str(h.shape()),
                expected: format!(
                    "(batch, {NETWORK_BANDS}, {MST_SIZE}, {MST_SIZE}); MST's mask shift-back is built for 256×256"
                ),
            });
        }
        Ok(dims)
    }

    fn check_guidance(&self, g: &MstMaskGuidance) -> Result<()> {
        if g.net_id != self.id {
            return Err(NetError::Input {
                what: "MST mask guidance".into(),
                got: "guidance computed by another MST instance".into(),
                expected: "this network's mask_guidance(phi)".into(),
            });
        }
        Ok(())
    }

    /// One sample; with `record`, also the activations the reference dumps.
    fn forward_sample(
        &self,
        x: FeatureMap,
        guidance: &MstMaskGuidance,
        record: bool,
    ) -> (FeatureMap, Option<MstActivations>) {
        let [enc0, enc1, bottleneck_embs, dec0, dec1] = &guidance.per_msab;
        let mut fea = self.embedding.forward(&x);
        leaky_relu_in_place(&mut fea.data, 0.1);
        let embedding = record.then(|| fea.clone());

        let mut skips = Vec::with_capacity(2);
        for (stage, embs) in self.encoder.iter().zip([enc0, enc1]) {
            fea = stage.msab.forward(fea, embs);
            skips.push(fea.clone());
            fea = stage.fea_down.forward(&fea);
        }
        fea = self.bottleneck.forward(fea, bottleneck_embs);
        let bottleneck = record.then(|| fea.clone());
        for (i, (stage, embs)) in self.decoder.iter().zip([dec0, dec1]).enumerate() {
            let up = stage.up.forward(&fea);
            fea = stage.fusion.forward(&up.concat_channels(&skips[1 - i]));
            fea = stage.msab.forward(fea, embs);
        }
        let mut out = self.mapping.forward(&fea);
        let acts = match (record, embedding, bottleneck) {
            (true, Some(embedding), Some(bottleneck)) => Some(MstActivations {
                embedding: batch_of_one(embedding),
                enc0_block0_mask_attn: batch_of_one(enc0[0].clone()),
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
    Tensor::new(shape, f.into_data()).expect("a feature map's data fits its shape")
}

/// Batch element `i` of an NCHW tensor as a feature map.
fn sample(t: &Tensor, i: usize) -> FeatureMap {
    let s = t.shape();
    let len = s[1] * s[2] * s[3];
    FeatureMap::from_slice(s[1], s[2], s[3], &t.data()[i * len..(i + 1) * len])
}
