//! ConvTranspose2d with kernel 2, stride 2, no padding (MST's up-sampler):
//! out[o, 2r+a, 2s+b] = bias[o] + Σ_c in[c, r, s] · W[c, o, a, b].

use rayon::prelude::*;

use super::matmul::{Mat, matmul};
use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;

pub(crate) struct ConvTranspose2x2 {
    /// (in, out, 2, 2) row-major, PyTorch's layout.
    weight: Vec<f32>,
    bias: Vec<f32>,
    in_ch: usize,
    out_ch: usize,
}

impl ConvTranspose2x2 {
    pub fn load(w: &mut WeightLoader, name: &str, in_ch: usize, out_ch: usize) -> Self {
        let weight = w
            .take(&format!("{name}.weight"), &[in_ch, out_ch, 2, 2])
            .into_data();
        let bias = w.take(&format!("{name}.bias"), &[out_ch]).into_data();
        Self {
            weight,
            bias,
            in_ch,
            out_ch,
        }
    }

    pub fn forward(&self, x: &FeatureMap) -> FeatureMap {
        assert_eq!(x.c, self.in_ch, "transposed conv channels");
        let n = x.plane();
        // T[(o, a, b), p] = Σ_c W[c, (o, a, b)] · in[c, p]: Wᵀ as a strided view.
        let taps = self.out_ch * 4;
        let mut t = FeatureMap::for_overwrite(taps, x.h, x.w);
        matmul(
            Mat::transposed(&self.weight, taps, self.in_ch, taps),
            Mat::rows(&x.data, self.in_ch, n, n),
            &mut t.data,
        );
        let (h2, w2) = (2 * x.h, 2 * x.w);
        let mut out = FeatureMap::for_overwrite(self.out_ch, h2, w2);
        out.data
            .par_chunks_mut(h2 * w2)
            .enumerate()
            .for_each(|(o, dst)| {
                for a in 0..2 {
                    for b in 0..2 {
                        let src = &t.data[(o * 4 + a * 2 + b) * n..][..n];
                        for r in 0..x.h {
                            let row = &mut dst[(2 * r + a) * w2..][..w2];
                            for s in 0..x.w {
                                row[2 * s + b] = src[r * x.w + s] + self.bias[o];
                            }
                        }
                    }
                }
            });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::conv::tests::pseudo_random;

    #[test]
    fn matches_the_definition() {
        let (ci, co, h, w) = (3, 2, 4, 5);
        let ct = ConvTranspose2x2 {
            weight: pseudo_random(ci * co * 4, 8),
            bias: pseudo_random(co, 9),
            in_ch: ci,
            out_ch: co,
        };
        let x = FeatureMap::from_vec(ci, h, w, pseudo_random(ci * h * w, 10));
        let got = ct.forward(&x);
        for o in 0..co {
            for y in 0..2 * h {
                for q in 0..2 * w {
                    let (r, s, a, b) = (y / 2, q / 2, y % 2, q % 2);
                    let mut acc = ct.bias[o];
                    for c in 0..ci {
                        acc +=
                            x.data[(c * h + r) * w + s] * ct.weight[((c * co + o) * 2 + a) * 2 + b];
                    }
                    assert!((got.data[(o * 2 * h + y) * 2 * w + q] - acc).abs() < 1e-5);
                }
            }
        }
    }
}
