//! MS-MSA, MST's mask-guided spectral-wise multi-head self-attention: the
//! attention map is d×d over channels (not pixels), so its cost is linear
//! in the image size.

use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;
use crate::ops::activation::softmax_in_place;
use crate::ops::conv::Conv2d;
use crate::ops::depthwise::DepthwiseConv2d;
use crate::ops::matmul::{Mat, SharedOut, matmul_into};
use crate::ops::pointwise::{Activation, MixWeights};

/// Channels per head in every MST stage.
pub(crate) const HEAD_DIM: usize = 28;

pub(crate) struct MsMsa {
    /// `to_q` and `to_k` stacked (2C × C): one kernel pass over x for both.
    to_qk: MixWeights,
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
        let mut qk = w.take(&format!("{name}.to_q.weight"), &[c, c]).into_data();
        qk.extend(w.take(&format!("{name}.to_k.weight"), &[c, c]).data());
        Self {
            to_qk: MixWeights::new(qk, 2 * c, c),
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
        // Q in channels 0 .. C, K in C .. 2C.
        let mut qk = FeatureMap::for_overwrite(2 * x.c, x.h, x.w);
        (self.to_qk).apply(&x.data, n, None, Activation::Identity, &mut qk.data);
        normalize_rows(&mut qk.data, n);
        let (q, k) = qk.data.split_at(x.c * n);
        let v_in = self.to_v.forward(x);
        let v = v_in.product(emb);

        let d = HEAD_DIM;
        let mut heads_out = FeatureMap::for_overwrite(x.c, x.h, x.w);
        for h in 0..self.heads {
            let rows = h * d * n..(h + 1) * d * n;
            // A[i, j] = Σ_p k̂[i, p] q̂[j, p]  (d × d)
            let mut attn = gram(&k[rows.clone()], &q[rows.clone()], d, n);
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

/// a · bᵀ for two (d × n) row-major matrices: d × d sums over n pixels,
/// split into pixel ranges summed in parallel (the result has too few
/// columns to split).
fn gram(a: &[f32], b: &[f32], d: usize, n: usize) -> Vec<f32> {
    use rayon::prelude::*;
    const PIXELS: usize = 8192;
    (0..n.div_ceil(PIXELS))
        .into_par_iter()
        .map(|t| {
            let (p0, p1) = (t * PIXELS, ((t + 1) * PIXELS).min(n));
            let mut part = vec![0.0f32; d * d];
            // SAFETY: `part` is this task's own, d × d.
            unsafe {
                matmul_into(
                    Mat::rows(&a[p0..], d, p1 - p0, n),
                    Mat::transposed(&b[p0..], p1 - p0, d, n),
                    SharedOut::new(&mut part),
                    0,
                    (d, 1),
                    false,
                )
            };
            part
        })
        .reduce_with(|mut s, p| {
            s.iter_mut().zip(&p).for_each(|(s, p)| *s += p);
            s
        })
        .unwrap_or_else(|| vec![0.0; d * d])
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::conv::tests::pseudo_random;

    #[test]
    fn gram_sums_every_pixel_range() {
        // 20 000 pixels: three parallel ranges, the last one partial.
        let (d, n) = (3, 20_000);
        let (a, b) = (pseudo_random(d * n, 31), pseudo_random(d * n, 32));
        let got = gram(&a, &b, d, n);
        for i in 0..d {
            for j in 0..d {
                let want: f64 = (0..n)
                    .map(|p| a[i * n + p] as f64 * b[j * n + p] as f64)
                    .sum();
                let g = got[i * d + j] as f64;
                assert!(
                    (g - want).abs() < 1e-3 * want.abs().max(1.0),
                    "({i},{j}): {g} vs {want}"
                );
            }
        }
    }
}
