//! Dense 2-D convolution (groups = 1, zero padding), as PyTorch's Conv2d:
//! im2col on tiles of output rows, one gemm per tile, tiles in parallel;
//! 3×3 "same" convolutions loaded with [`Conv2d::load`] go through Winograd
//! F(2×2, 3×3) instead ([`super::winograd`]).

use rayon::prelude::*;

use super::matmul::{Mat, SharedOut, matmul_into};
use super::pointwise::{Activation, MixWeights};
use super::winograd::WinogradWeights;
use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;

/// Output columns per im2col tile: the column buffer (C·k²·cols floats)
/// then stays near the L2/L3 caches, and 256² images give 64 tiles.
const TILE_COLS: usize = 1024;

pub(crate) struct Conv2d {
    /// (out, in, k, k) row-major = the (out × in·k²) matrix of the gemm.
    weight: Vec<f32>,
    bias: Option<Vec<f32>>,
    out_ch: usize,
    in_ch: usize,
    k: usize,
    stride: usize,
    pad: usize,
    /// The weights transformed for Winograd F(2×2, 3×3), for 3×3 "same"
    /// convolutions (2.25× fewer multiplications than im2col + gemm).
    winograd: Option<WinogradWeights>,
    /// The weights packed for the channel-mixing kernel, for 1×1 convolutions.
    mix: Option<MixWeights>,
}

impl Conv2d {
    /// A k×k convolution with stride 1 and "same" padding k/2: takes
    /// `{name}.weight` (out, in, k, k) and, if `bias`, `{name}.bias`.
    pub fn load(
        w: &mut WeightLoader,
        name: &str,
        in_ch: usize,
        out_ch: usize,
        k: usize,
        bias: bool,
    ) -> Self {
        let weight = w
            .take(&format!("{name}.weight"), &[out_ch, in_ch, k, k])
            .into_data();
        let bias = bias.then(|| w.take(&format!("{name}.bias"), &[out_ch]).into_data());
        let winograd = (k == 3).then(|| WinogradWeights::new(&weight, out_ch, in_ch));
        let mix = (k == 1).then(|| MixWeights::new(weight.clone(), out_ch, in_ch));
        Self {
            weight,
            bias,
            out_ch,
            in_ch,
            k,
            stride: 1,
            pad: k / 2,
            winograd,
            mix,
        }
    }

    /// A k×k convolution with the given stride and padding and no bias
    /// (MST's down-samplers): takes `{name}.weight` (out, in, k, k).
    pub fn load_strided(
        w: &mut WeightLoader,
        name: &str,
        in_ch: usize,
        out_ch: usize,
        k: usize,
        stride: usize,
        pad: usize,
    ) -> Self {
        let weight = w
            .take(&format!("{name}.weight"), &[out_ch, in_ch, k, k])
            .into_data();
        Self {
            weight,
            bias: None,
            out_ch,
            in_ch,
            k,
            stride,
            pad,
            winograd: None,
            mix: None,
        }
    }

    /// A Linear layer `{name}.weight` (out, in) [+ `{name}.bias`], applied to
    /// channel-first maps: PyTorch's Linear over the channels of each pixel
    /// is exactly a 1×1 convolution.
    pub fn load_linear(
        w: &mut WeightLoader,
        name: &str,
        in_ch: usize,
        out_ch: usize,
        bias: bool,
    ) -> Self {
        let weight = w
            .take(&format!("{name}.weight"), &[out_ch, in_ch])
            .into_data();
        let bias = bias.then(|| w.take(&format!("{name}.bias"), &[out_ch]).into_data());
        let mix = Some(MixWeights::new(weight.clone(), out_ch, in_ch));
        Self {
            weight,
            bias,
            out_ch,
            in_ch,
            k: 1,
            stride: 1,
            pad: 0,
            winograd: None,
            mix,
        }
    }

    pub fn out_size(&self, h: usize, w: usize) -> (usize, usize) {
        let f = |n: usize| (n + 2 * self.pad - self.k) / self.stride + 1;
        (f(h), f(w))
    }

    pub fn forward(&self, x: &FeatureMap) -> FeatureMap {
        self.forward_act(x, Activation::Identity)
    }

    /// GELU(conv(x)); for 1×1 convolutions the GELU runs on each block of
    /// outputs while it is in cache (saves a pass over the map).
    pub fn forward_gelu(&self, x: &FeatureMap) -> FeatureMap {
        self.forward_act(x, Activation::Gelu)
    }

    fn forward_act(&self, x: &FeatureMap, act: Activation) -> FeatureMap {
        assert_eq!(x.c, self.in_ch, "conv input channels");
        if let Some(mix) = &self.mix {
            let mut out = FeatureMap::for_overwrite(self.out_ch, x.h, x.w);
            mix.apply(&x.data, x.plane(), self.bias.as_deref(), act, &mut out.data);
            return out;
        }
        let mut out = self.forward_unfused(x);
        if act == Activation::Gelu {
            super::activation::gelu_in_place(&mut out.data);
        }
        out
    }

    /// Winograd or im2col + gemm, then the bias.
    fn forward_unfused(&self, x: &FeatureMap) -> FeatureMap {
        if let Some(wg) = &self.winograd {
            let mut out = wg.forward(x);
            if let Some(b) = &self.bias {
                add_channel_bias(&mut out, b);
            }
            return out;
        }
        let (ho, wo) = self.out_size(x.h, x.w);
        let mut out = FeatureMap::for_overwrite(self.out_ch, ho, wo);
        let kk = self.in_ch * self.k * self.k;
        let wmat = Mat::rows(&self.weight, self.out_ch, kk, kk);
        let rows_per_tile = (TILE_COLS / wo).max(1);
        let shared = SharedOut::new(&mut out.data);
        (0..ho.div_ceil(rows_per_tile))
            .into_par_iter()
            .for_each(|t| {
                let r0 = t * rows_per_tile;
                let r1 = (r0 + rows_per_tile).min(ho);
                let cols = (r1 - r0) * wo;
                let mut col = take_scratch();
                self.im2col(x, r0, r1, wo, &mut col);
                // SAFETY: each tile writes only its own output rows r0..r1
                // (columns [r0*wo, r1*wo) of every output channel).
                unsafe {
                    matmul_into(
                        wmat,
                        Mat::rows(&col, kk, cols, cols),
                        shared,
                        r0 * wo,
                        (ho * wo, 1),
                        false,
                    )
                };
                return_scratch(col);
            });
        if let Some(b) = &self.bias {
            add_channel_bias(&mut out, b);
        }
        out
    }

    /// Fills `col` with the (in·k² × (r1−r0)·wo) column matrix of output
    /// rows r0..r1. Every element is written (padding as explicit zeros), so
    /// a reused buffer needs no clearing.
    fn im2col(&self, x: &FeatureMap, r0: usize, r1: usize, wo: usize, col: &mut Vec<f32>) {
        let (k, s, p) = (self.k, self.stride, self.pad as isize);
        let cols = (r1 - r0) * wo;
        col.resize(self.in_ch * k * k * cols, 0.0);
        for c in 0..self.in_ch {
            let plane = x.channel(c);
            for ky in 0..k {
                for kx in 0..k {
                    let row = &mut col[((c * k + ky) * k + kx) * cols..][..cols];
                    for r in r0..r1 {
                        let iy = (r * s + ky) as isize - p;
                        let dst = &mut row[(r - r0) * wo..][..wo];
                        if iy < 0 || iy >= x.h as isize {
                            dst.fill(0.0);
                            continue;
                        }
                        let src = &plane[iy as usize * x.w..][..x.w];
                        // Valid ox: 0 <= ox*s + kx - p < w.
                        let shift = kx as isize - p;
                        let ox0 = if shift < 0 {
                            ((-shift) as usize).div_ceil(s)
                        } else {
                            0
                        };
                        let ox1 = ((x.w as isize - shift + s as isize - 1) / s as isize)
                            .clamp(0, wo as isize) as usize;
                        let ox0 = ox0.min(wo);
                        let ox1 = ox1.max(ox0);
                        dst[..ox0].fill(0.0);
                        dst[ox1..].fill(0.0);
                        if s == 1 {
                            if ox1 > ox0 {
                                let i0 = (ox0 as isize + shift) as usize;
                                dst[ox0..ox1].copy_from_slice(&src[i0..i0 + (ox1 - ox0)]);
                            }
                        } else {
                            for ox in ox0..ox1 {
                                dst[ox] = src[(ox as isize * s as isize + shift) as usize];
                            }
                        }
                    }
                }
            }
        }
    }
}

thread_local! {
    /// Each rayon worker keeps its im2col buffer between tiles and layers
    /// (a fresh multi-MB allocation per tile costs page faults and clearing).
    static IM2COL_SCRATCH: std::cell::Cell<Vec<f32>> = const { std::cell::Cell::new(Vec::new()) };
}

fn take_scratch() -> Vec<f32> {
    IM2COL_SCRATCH.with(|c| c.take())
}

fn return_scratch(v: Vec<f32>) {
    IM2COL_SCRATCH.with(|c| c.set(v));
}

/// `x[c, …] += b[c]`, parallel over channels.
pub(crate) fn add_channel_bias(x: &mut FeatureMap, b: &[f32]) {
    let plane = x.plane();
    x.data
        .par_chunks_mut(plane)
        .zip(b.par_iter())
        .for_each(|(ch, &bc)| ch.iter_mut().for_each(|v| *v += bc));
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Direct definition of PyTorch's Conv2d, for checking.
    pub fn naive_conv(x: &FeatureMap, c: &Conv2d) -> FeatureMap {
        let (ho, wo) = c.out_size(x.h, x.w);
        let mut out = FeatureMap::zeros(c.out_ch, ho, wo);
        for o in 0..c.out_ch {
            for r in 0..ho {
                for q in 0..wo {
                    let mut acc = c.bias.as_ref().map_or(0.0, |b| b[o]);
                    for i in 0..c.in_ch {
                        for ky in 0..c.k {
                            for kx in 0..c.k {
                                let iy = (r * c.stride + ky) as isize - c.pad as isize;
                                let ix = (q * c.stride + kx) as isize - c.pad as isize;
                                if iy >= 0 && ix >= 0 && (iy as usize) < x.h && (ix as usize) < x.w
                                {
                                    acc += c.weight[((o * c.in_ch + i) * c.k + ky) * c.k + kx]
                                        * x.data[(i * x.h + iy as usize) * x.w + ix as usize];
                                }
                            }
                        }
                    }
                    out.data[(o * ho + r) * wo + q] = acc;
                }
            }
        }
        out
    }

    /// The largest |got − want|, infinite where `got` is NaN (an element an
    /// op left unwritten, see `FeatureMap::for_overwrite`).
    pub fn max_abs_err(got: &[f32], want: &[f32]) -> f32 {
        assert_eq!(got.len(), want.len(), "lengths");
        (got.iter().zip(want))
            .map(|(a, b)| {
                if a.is_nan() {
                    f32::INFINITY
                } else {
                    (a - b).abs()
                }
            })
            .fold(0.0, f32::max)
    }

    pub fn pseudo_random(n: usize, seed: u32) -> Vec<f32> {
        let mut s = seed.wrapping_mul(2654435761).wrapping_add(1);
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                (s % 2001) as f32 / 1000.0 - 1.0
            })
            .collect()
    }

    #[test]
    fn matches_the_definition_for_each_kernel_stride_and_padding() {
        for &(k, stride, pad, h, w) in &[
            (3, 1, 1, 9, 13),
            (1, 1, 0, 5, 7),
            (4, 2, 1, 10, 15),
            (5, 1, 2, 6, 4),
            (3, 2, 0, 11, 8),
        ] {
            let (ci, co) = (3, 4);
            let weight = pseudo_random(co * ci * k * k, 1);
            let mut conv = Conv2d {
                winograd: None,
                mix: None,
                weight: weight.clone(),
                bias: Some(pseudo_random(co, 2)),
                out_ch: co,
                in_ch: ci,
                k,
                stride,
                pad,
            };
            let x = FeatureMap::from_vec(ci, h, w, pseudo_random(ci * h * w, 3));
            let want = naive_conv(&x, &conv);
            let mut gelu_want = want.clone();
            crate::ops::activation::gelu_in_place(&mut gelu_want.data);
            let check = |conv: &Conv2d, path: &str| {
                for (got, want) in [
                    (conv.forward(&x), &want),
                    (conv.forward_gelu(&x), &gelu_want),
                ] {
                    assert_eq!((got.h, got.w), (want.h, want.w));
                    let err = max_abs_err(&got.data, &want.data);
                    assert!(err < 1e-5, "{path} k{k} s{stride} p{pad}: {err}");
                }
            };
            check(&conv, "im2col");
            if (k, stride, pad) == (3, 1, 1) {
                conv.winograd = Some(WinogradWeights::new(&weight, co, ci));
                check(&conv, "winograd");
            }
            if (k, stride, pad) == (1, 1, 0) {
                conv.mix = Some(MixWeights::new(weight.clone(), co, ci));
                check(&conv, "channel mix");
            }
        }
    }
}
