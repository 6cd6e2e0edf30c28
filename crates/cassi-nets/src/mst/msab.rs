//! MSAB, MST's mask-guided spectral-wise attention block: n times
//! x = MS-MSA(x, mask) + x, then x = FFN(LayerNorm(x)) + x.

use super::mask_guide::MaskGuide;
use super::ms_msa::MsMsa;
use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;
use crate::ops::conv::Conv2d;
use crate::ops::depthwise::DepthwiseConv2d;
use crate::ops::norm::LayerNormChannels;

/// The PreNorm feed-forward: 1×1 C→4C, GELU, depthwise 3×3, GELU, 1×1 4C→C.
struct FeedForward {
    norm: LayerNormChannels,
    expand: Conv2d,
    depthwise: DepthwiseConv2d,
    reduce: Conv2d,
}

impl FeedForward {
    fn load(w: &mut WeightLoader, name: &str, c: usize) -> Self {
        Self {
            norm: LayerNormChannels::load(w, &format!("{name}.norm"), c),
            expand: Conv2d::load(w, &format!("{name}.fn.net.0"), c, 4 * c, 1, false),
            depthwise: DepthwiseConv2d::load(w, &format!("{name}.fn.net.2"), 4 * c, 3, false),
            reduce: Conv2d::load(w, &format!("{name}.fn.net.4"), 4 * c, c, 1, false),
        }
    }

    fn forward(&self, x: &FeatureMap) -> FeatureMap {
        let t = self.expand.forward_gelu(&self.norm.forward(x));
        self.reduce.forward(&self.depthwise.forward_gelu(&t))
    }
}

struct Block {
    mask_guide: MaskGuide,
    attention: MsMsa,
    feed_forward: FeedForward,
}

pub(crate) struct Msab {
    blocks: Vec<Block>,
}

impl Msab {
    /// `{name}.blocks.{j}.0` (MS-MSA with its `mm`) and `.1` (FFN), j < n.
    pub fn load(w: &mut WeightLoader, name: &str, c: usize, n: usize) -> Self {
        let blocks = (0..n)
            .map(|j| {
                let b = format!("{name}.blocks.{j}");
                Block {
                    mask_guide: MaskGuide::load(w, &format!("{b}.0.mm"), c),
                    attention: MsMsa::load(w, &format!("{b}.0"), c),
                    feed_forward: FeedForward::load(w, &format!("{b}.1"), c),
                }
            })
            .collect();
        Self { blocks }
    }

    /// Each block's mask embedding (after shift-back) for the mask at this
    /// level: input-independent, so computed once per coded aperture.
    pub fn mask_embeddings(&self, mask: &FeatureMap) -> Vec<FeatureMap> {
        self.blocks
            .iter()
            .map(|b| b.mask_guide.forward(mask))
            .collect()
    }

    /// `embeddings` from [`mask_embeddings`](Self::mask_embeddings), one per block.
    pub fn forward(&self, x: FeatureMap, embeddings: &[FeatureMap]) -> FeatureMap {
        assert_eq!(
            embeddings.len(),
            self.blocks.len(),
            "one mask embedding per block"
        );
        let mut x = x;
        for (b, emb) in self.blocks.iter().zip(embeddings) {
            let a = b.attention.forward(&x, emb);
            x.add_assign(&a);
            let f = b.feed_forward.forward(&x);
            x.add_assign(&f);
        }
        x
    }
}
