//! Depthwise 2-D convolution (groups = channels, one k×k filter per
//! channel, stride 1, zero padding k/2), parallel over channels.

use rayon::prelude::*;

use super::activation::gelu_slice;
use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;

pub(crate) struct DepthwiseConv2d {
    /// (channels, 1, k, k) row-major.
    weight: Vec<f32>,
    bias: Option<Vec<f32>>,
    channels: usize,
    k: usize,
}

impl DepthwiseConv2d {
    /// Takes `{name}.weight` (channels, 1, k, k) and, if `bias`, `{name}.bias`.
    pub fn load(w: &mut WeightLoader, name: &str, channels: usize, k: usize, bias: bool) -> Self {
        let weight = w
            .take(&format!("{name}.weight"), &[channels, 1, k, k])
            .into_data();
        let bias = bias.then(|| w.take(&format!("{name}.bias"), &[channels]).into_data());
        Self {
            weight,
            bias,
            channels,
            k,
        }
    }

    pub fn forward(&self, x: &FeatureMap) -> FeatureMap {
        self.run(x, false)
    }

    /// GELU(conv(x)), the activation applied to each output row while it is
    /// still in L1 (saves a pass over the map; same numbers as separately).
    pub fn forward_gelu(&self, x: &FeatureMap) -> FeatureMap {
        self.run(x, true)
    }

    fn run(&self, x: &FeatureMap, gelu: bool) -> FeatureMap {
        assert_eq!(x.c, self.channels, "depthwise conv channels");
        let (h, w, k) = (x.h, x.w, self.k);
        let mut out = FeatureMap::for_overwrite(x.c, h, w);
        out.data
            .par_chunks_mut(h * w)
            .enumerate()
            .for_each(|(c, dst)| {
                let bias = self.bias.as_ref().map_or(0.0, |b| b[c]);
                let taps = &self.weight[c * k * k..(c + 1) * k * k];
                depthwise_plane(x.channel(c), dst, taps, k, w, bias, gelu);
            });
        out
    }
}

super::simd::avx2_dispatch! {
    /// One channel: out = bias + Σ taps ⊛ src (zero padding k/2), computed
    /// row by row so the k input rows and the output row stay in L1; then
    /// GELU on the row if `gelu`.
    fn depthwise_plane(
        src: &[f32],
        dst: &mut [f32],
        taps: &[f32],
        k: usize,
        w: usize,
        bias: f32,
        gelu: bool,
    ) {
        let h = src.len() / w;
        let p = (k / 2) as isize;
        for (y, out_row) in dst.chunks_exact_mut(w).enumerate() {
            let interior = y >= k / 2 && y + k / 2 < h && w >= k;
            if interior && (k == 3 || k == 5) {
                let rows = &src[(y - k / 2) * w..][..k * w];
                if k == 3 {
                    interior_row::<3>(rows, out_row, taps, bias);
                } else {
                    interior_row::<5>(rows, out_row, taps, bias);
                }
                if gelu {
                    gelu_slice(out_row);
                }
                continue;
            }
            out_row.fill(bias);
            for ky in 0..k {
                let iy = y as isize + ky as isize - p;
                if iy < 0 || iy >= h as isize {
                    continue;
                }
                let in_row = &src[iy as usize * w..][..w];
                for kx in 0..k {
                    let wv = taps[ky * k + kx];
                    // input col = output col + shift, valid where both are in range
                    let shift = kx as isize - p;
                    let x0 = (-shift).max(0) as usize;
                    let x1 = (w as isize - shift).clamp(0, w as isize) as usize;
                    if x1 <= x0 {
                        continue;
                    }
                    let i0 = (x0 as isize + shift) as usize;
                    let ins = &in_row[i0..i0 + (x1 - x0)];
                    for (o, i) in out_row[x0..x1].iter_mut().zip(ins) {
                        *o += wv * i;
                    }
                }
            }
            if gelu {
                gelu_slice(out_row);
            }
        }
    }
}

/// One output row of a K×K depthwise conv whose K input rows (`rows`,
/// K·w floats) all exist: each output written once, eight at a time, from
/// taps held in registers (the generic loop re-reads and re-writes the row
/// per tap). Taps are added in the generic loop's order, so the results are
/// bit-identical to it.
#[inline(always)]
fn interior_row<const K: usize>(rows: &[f32], out: &mut [f32], taps: &[f32], bias: f32) {
    const LANES: usize = 8;
    let w = out.len();
    let p = K / 2;
    let t = &taps[..K * K];
    let row: [&[f32]; K] = std::array::from_fn(|ky| &rows[ky * w..(ky + 1) * w]);
    let (x0, x1) = (p, w - p);
    let mut x = x0;
    while x + LANES <= x1 {
        let mut acc = [bias; LANES];
        for ky in 0..K {
            for kx in 0..K {
                let tap = t[ky * K + kx];
                let v: &[f32; LANES] = row[ky][x + kx - p..][..LANES].try_into().unwrap();
                for l in 0..LANES {
                    acc[l] += tap * v[l];
                }
            }
        }
        out[x..x + LANES].copy_from_slice(&acc);
        x += LANES;
    }
    for x in (0..x0).chain(x..w) {
        let mut acc = bias;
        for ky in 0..K {
            for kx in 0..K {
                // Skips the taps outside the row (zero padding).
                if let Some(v) = (x + kx).checked_sub(p).and_then(|ix| row[ky].get(ix)) {
                    acc += t[ky * K + kx] * v;
                }
            }
        }
        out[x] = acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::conv::tests::pseudo_random;

    #[test]
    fn fused_gelu_equals_conv_then_gelu() {
        let dw = DepthwiseConv2d {
            weight: pseudo_random(4 * 9, 11),
            bias: None,
            channels: 4,
            k: 3,
        };
        // 17 columns: GELU's eight-lane path and its scalar tail on each row.
        let x = FeatureMap::from_vec(4, 5, 17, pseudo_random(4 * 5 * 17, 12));
        let mut want = dw.forward(&x);
        want.data.chunks_mut(17).for_each(gelu_slice);
        assert_eq!(dw.forward_gelu(&x), want);
    }

    #[test]
    fn matches_the_definition() {
        // 3×3 and 5×5 take the interior-row path (with a tail past eight
        // lanes at 23 columns); 2×2 and 3×3 maps its fallbacks.
        for (k, h, w) in [
            (1, 7, 9),
            (3, 7, 9),
            (5, 7, 9),
            (3, 6, 23),
            (5, 9, 23),
            (3, 2, 2),
            (3, 3, 3),
        ] {
            let c = 3;
            let dw = DepthwiseConv2d {
                weight: pseudo_random(c * k * k, 5),
                bias: Some(pseudo_random(c, 6)),
                channels: c,
                k,
            };
            let x = FeatureMap::from_vec(c, h, w, pseudo_random(c * h * w, 7));
            let got = dw.forward(&x);
            let p = (k / 2) as isize;
            for ch in 0..c {
                for y in 0..h {
                    for q in 0..w {
                        let mut acc = dw.bias.as_ref().unwrap()[ch];
                        for ky in 0..k {
                            for kx in 0..k {
                                let (iy, ix) =
                                    (y as isize + ky as isize - p, q as isize + kx as isize - p);
                                if iy >= 0 && ix >= 0 && (iy as usize) < h && (ix as usize) < w {
                                    acc += dw.weight[(ch * k + ky) * k + kx]
                                        * x.data[(ch * h + iy as usize) * w + ix as usize];
                                }
                            }
                        }
                        let g = got.data[(ch * h + y) * w + q];
                        assert!((g - acc).abs() < 1e-5, "k{k} ({ch},{y},{q}): {g} vs {acc}");
                    }
                }
            }
        }
    }
}
