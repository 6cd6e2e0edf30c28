//! MS-MSA, MST's mask-guided spectral-wise multi-head self-attention: the
//! attention map is d×d over channels (not pixels), so its cost is linear
//! in the image size.

use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;
use crate::ops::activation::softmax_in_place;
use crate::ops::conv::Conv2d;
use crate::ops::depthwise::DepthwiseConv2d;
use crate::ops::matmul::{Mat, matmul};
use crate::ops::pointwise::{Activation, MixWeights};

/// Channels per head in every MST stage.
pub(crate) const HEAD_DIM: usize = 28;

pub(crate) struct MsMsa {
    to_q: Conv2d,
    to_k: Conv2d,
    to_v: Conv2d,
    rescale: Vec<f32>,
    proj: Conv2d,
    pos_emb0: DepthwiseConv2d,
    pos_emb2: DepthwiseConv2d,
    heads: usize,
}

impl MsMsa {
    pub fn load(w: &mut WeightLoader, name: &str, c: usize) -> Self {
        let heads = c / HEAD_DIM;
        Self {
            to_q: Conv2d::load_linear(w, &format!("{name}.to_q"), c, c, false),
            to_k: Conv2d::load_linear(w, &format!("{name}.to_k"), c, c, false),
            to_v: Conv2d::load_linear(w, &format!("{name}.to_v"), c, c, false),
            rescale: w
                .take(&format!("{name}.rescale"), &[heads, 1, 1])
                .into_data(),
            proj: Conv2d::load_linear(w, &format!("{name}.proj"), c, c, true),
            pos_emb0: DepthwiseConv2d::load(w, &format!("{name}.pos_emb.0"), c, 3, false),
            pos_emb2: DepthwiseConv2d::load(w, &format!("{name}.pos_emb.2"), c, 3, false),
            heads,
        }
    }

    /// x (C, h, w) and the mask embedding emb (C, h, w) → out_c + out_p.
    pub fn forward(&self, x: &FeatureMap, emb: &FeatureMap) -> FeatureMap {
        let n = x.plane();
        let mut q = self.to_q.forward(x);
        let mut k = self.to_k.forward(x);
        let v_in = self.to_v.forward(x);
        let v = v_in.product(emb);
        normalize_rows(&mut q.data, n);
        normalize_rows(&mut k.data, n);

        let d = HEAD_DIM;
        let mut heads_out = FeatureMap::for_overwrite(x.c, x.h, x.w);
        for h in 0..self.heads {
            let rows = h * d * n..(h + 1) * d * n;
            // A[i, j] = Σ_p k̂[i, p] q̂[j, p]  (d × d)
            let mut attn = vec![0.0f32; d * d];
            matmul(
                Mat::rows(&k.data[rows.clone()], d, n, n),
                Mat::transposed(&q.data[rows.clone()], n, d, n),
                &mut attn,
            );
            for row in attn.chunks_mut(d) {
                row.iter_mut().for_each(|a| *a *= self.rescale[h]);
                softmax_in_place(row);
            }
            MixWeights::new(attn, d, d).apply(
                &v.data[rows.clone()],
                n,
                None,
                Activation::Identity,
                &mut heads_out.data[rows],
            );
        }
        let mut out = self.proj.forward(&heads_out);
        // Positional embedding from V before the mask modulation.
        let p = self.pos_emb0.forward_gelu(&v_in);
        out.add_assign(&self.pos_emb2.forward(&p));
        out
    }
}

/// F.normalize(dim=-1): each length-n row divided by max(‖row‖₂, 1e-12).
fn normalize_rows(data: &mut [f32], n: usize) {
    use rayon::prelude::*;
    data.par_chunks_mut(n).for_each(|row| {
        let ss: f64 = row.iter().map(|&v| (v as f64) * (v as f64)).sum();
        let inv = (1.0 / ss.sqrt().max(1e-12)) as f32;
        row.iter_mut().for_each(|v| *v *= inv);
    });
}
