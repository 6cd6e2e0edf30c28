//! 3×3 "same" convolutions (stride 1, padding 1) by Winograd's minimal
//! filtering F(2×2, 3×3) (Lavin & Gray 2016): each 2×2 output tile costs 16
//! multiplications per channel pair instead of 36, so the products — most
//! of HDNet's and HSI-SDeCNN's time — shrink 2.25×. Tiles are processed in
//! blocks of tile rows: transform the block's 4×4 input patches (V), 16
//! products U[ξ] · V[ξ] (U: the transformed weights), transform back.

use rayon::prelude::*;

use super::matmul::SharedOut;
use super::pointwise::{Activation, MixWeights};
use crate::fmap::FeatureMap;

/// Output tiles (2×2 each) per block: the block's V and M scratch
/// (16 × channels × tiles floats each) then stays near the L2 cache.
const BLOCK_TILES: usize = 256;

/// Weights transformed for F(2×2, 3×3): u[ξ] is the (out × in) matrix of
/// the ξ-th element (ξ = 4a + b) of G g Gᵀ for every channel pair, packed
/// for the channel-mixing kernel (each product U[ξ]·V[ξ] is one).
pub(crate) struct WinogradWeights {
    u: Vec<MixWeights>,
    out_ch: usize,
    in_ch: usize,
}

impl WinogradWeights {
    /// From (out, in, 3, 3) row-major weights.
    pub fn new(weight: &[f32], out_ch: usize, in_ch: usize) -> Self {
        assert_eq!(weight.len(), out_ch * in_ch * 9, "3×3 weights");
        let mut u = vec![0.0f32; 16 * out_ch * in_ch];
        for o in 0..out_ch {
            for i in 0..in_ch {
                let g = &weight[(o * in_ch + i) * 9..][..9];
                // t = G g (4×3), then t Gᵀ (4×4); G = [1 0 0; ½ ½ ½; ½ −½ ½; 0 0 1].
                let mut t = [[0.0f32; 3]; 4];
                for c in 0..3 {
                    let (g0, g1, g2) = (g[c], g[3 + c], g[6 + c]);
                    t[0][c] = g0;
                    t[1][c] = 0.5 * (g0 + g1 + g2);
                    t[2][c] = 0.5 * (g0 - g1 + g2);
                    t[3][c] = g2;
                }
                for (a, row) in t.iter().enumerate() {
                    let v = [
                        row[0],
                        0.5 * (row[0] + row[1] + row[2]),
                        0.5 * (row[0] - row[1] + row[2]),
                        row[2],
                    ];
                    for (b, &val) in v.iter().enumerate() {
                        u[((4 * a + b) * out_ch + o) * in_ch + i] = val;
                    }
                }
            }
        }
        let u = u
            .chunks_exact(out_ch * in_ch)
            .map(|m| MixWeights::new(m.to_vec(), out_ch, in_ch))
            .collect();
        Self { u, out_ch, in_ch }
    }

    /// The 3×3, stride-1, padding-1 convolution of `x` (no bias).
    pub fn forward(&self, x: &FeatureMap) -> FeatureMap {
        assert_eq!(x.c, self.in_ch, "conv input channels");
        let (h, w) = (x.h, x.w);
        let (th, tw) = (h.div_ceil(2), w.div_ceil(2));
        let rows_per_block = (BLOCK_TILES / tw).max(1);
        let mut out = FeatureMap::for_overwrite(self.out_ch, h, w);
        let shared = SharedOut::new(&mut out.data);
        (0..th.div_ceil(rows_per_block))
            .into_par_iter()
            .for_each(|blk| {
                let ty0 = blk * rows_per_block;
                let ty1 = (ty0 + rows_per_block).min(th);
                // SAFETY: a block writes only output rows 2·ty0 .. 2·ty1.
                unsafe { self.block(x, ty0, ty1, tw, shared) };
            });
        out
    }

    /// Tile rows ty0..ty1 of the output. The transforms run along whole
    /// rows of tiles (vectorisable loops, no per-pixel bounds checks).
    ///
    /// # Safety
    /// No other thread may write output rows 2·ty0 .. 2·ty1 meanwhile.
    unsafe fn block(&self, x: &FeatureMap, ty0: usize, ty1: usize, tw: usize, out: SharedOut) {
        let (h, w) = (x.h, x.w);
        let tiles = (ty1 - ty0) * tw;
        let (ci, co) = (self.in_ch, self.out_ch);
        // A padded input row holds columns −1 … 2·tw (zero outside the image).
        let wp = 2 * tw + 2;
        let mut scratch = take_scratch();
        let (v, m) = scratch.split(16 * ci * tiles, 16 * co * tiles);
        let mut d = vec![0.0f32; 4 * wp];
        let mut r = vec![0.0f32; 4 * wp];
        for i in 0..ci {
            let plane = x.channel(i);
            for ty in ty0..ty1 {
                for a in 0..4 {
                    let row = &mut d[a * wp..(a + 1) * wp];
                    row.fill(0.0);
                    let y = (2 * ty + a) as isize - 1;
                    if y >= 0 && (y as usize) < h {
                        row[1..1 + w].copy_from_slice(&plane[y as usize * w..][..w]);
                    }
                }
                // Bᵀ d over rows, Bᵀ = [1 0 −1 0; 0 1 1 0; 0 −1 1 0; 0 1 0 −1].
                {
                    let (d0, rest) = d.split_at(wp);
                    let (d1, rest) = rest.split_at(wp);
                    let (d2, d3) = rest.split_at(wp);
                    let (r0, rest) = r.split_at_mut(wp);
                    let (r1, rest) = rest.split_at_mut(wp);
                    let (r2, r3) = rest.split_at_mut(wp);
                    for j in 0..wp {
                        r0[j] = d0[j] - d2[j];
                        r1[j] = d1[j] + d2[j];
                        r2[j] = d2[j] - d1[j];
                        r3[j] = d1[j] - d3[j];
                    }
                }
                // (·) B over the columns of each tile.
                let t0 = (ty - ty0) * tw;
                for a in 0..4 {
                    let ra = &r[a * wp..(a + 1) * wp];
                    let slab = |b: usize| ((4 * a + b) * ci + i) * tiles + t0;
                    let dst = &mut v[slab(0)..][..tw];
                    for (tx, o) in dst.iter_mut().enumerate() {
                        *o = ra[2 * tx] - ra[2 * tx + 2];
                    }
                    let dst = &mut v[slab(1)..][..tw];
                    for (tx, o) in dst.iter_mut().enumerate() {
                        *o = ra[2 * tx + 1] + ra[2 * tx + 2];
                    }
                    let dst = &mut v[slab(2)..][..tw];
                    for (tx, o) in dst.iter_mut().enumerate() {
                        *o = ra[2 * tx + 2] - ra[2 * tx + 1];
                    }
                    let dst = &mut v[slab(3)..][..tw];
                    for (tx, o) in dst.iter_mut().enumerate() {
                        *o = ra[2 * tx + 1] - ra[2 * tx + 3];
                    }
                }
            }
        }
        for (xi, u) in self.u.iter().enumerate() {
            u.apply_serial(
                &v[xi * ci * tiles..][..ci * tiles],
                tiles,
                None,
                Activation::Identity,
                &mut m[xi * co * tiles..][..co * tiles],
            );
        }
        // Aᵀ M A with Aᵀ = [1 1 1 0; 0 1 −1 −1]: first over rows (s), then columns.
        let mut s = vec![0.0f32; 8 * tw];
        for o in 0..co {
            for ty in ty0..ty1 {
                let t0 = (ty - ty0) * tw;
                let mm = |a: usize, b: usize| &m[((4 * a + b) * co + o) * tiles + t0..][..tw];
                for b in 0..4 {
                    let (m0, m1, m2, m3) = (mm(0, b), mm(1, b), mm(2, b), mm(3, b));
                    let (s0, s1) = s.split_at_mut(4 * tw);
                    let (s0, s1) = (&mut s0[b * tw..][..tw], &mut s1[b * tw..][..tw]);
                    for t in 0..tw {
                        s0[t] = m0[t] + m1[t] + m2[t];
                        s1[t] = m1[t] - m2[t] - m3[t];
                    }
                }
                for dy in 0..2 {
                    let row = 2 * ty + dy;
                    if row >= h {
                        continue;
                    }
                    let sr = &s[dy * 4 * tw..(dy + 1) * 4 * tw];
                    let (c0, c1, c2, c3) = (
                        &sr[..tw],
                        &sr[tw..2 * tw],
                        &sr[2 * tw..3 * tw],
                        &sr[3 * tw..],
                    );
                    // SAFETY: output row `row` of channel `o` is in this block's rows.
                    let dst = unsafe { out.slice_mut((o * h + row) * w, w) };
                    for tx in 0..tw {
                        dst[2 * tx] = c0[tx] + c1[tx] + c2[tx];
                        if 2 * tx + 1 < w {
                            dst[2 * tx + 1] = c1[tx] - c2[tx] - c3[tx];
                        }
                    }
                }
            }
        }
        return_scratch(scratch);
    }
}

/// Per-worker V and M buffers, reused between blocks and layers (every
/// element is written before it is read, so they are never cleared).
#[derive(Default)]
struct Scratch {
    buf: Vec<f32>,
}

impl Scratch {
    fn split(&mut self, v_len: usize, m_len: usize) -> (&mut [f32], &mut [f32]) {
        if self.buf.len() < v_len + m_len {
            self.buf.resize(v_len + m_len, 0.0);
        }
        let (v, rest) = self.buf.split_at_mut(v_len);
        (v, &mut rest[..m_len])
    }
}

thread_local! {
    static SCRATCH: std::cell::Cell<Scratch> = const { std::cell::Cell::new(Scratch { buf: Vec::new() }) };
}

fn take_scratch() -> Scratch {
    SCRATCH.with(|c| c.take())
}

fn return_scratch(s: Scratch) {
    SCRATCH.with(|c| c.set(s));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::conv::tests::pseudo_random;

    /// Direct 3×3 convolution with zero padding 1, no bias.
    fn direct(weight: &[f32], x: &FeatureMap, co: usize) -> Vec<f32> {
        let (ci, h, w) = (x.c, x.h, x.w);
        let mut out = vec![0.0f32; co * h * w];
        for o in 0..co {
            for r in 0..h {
                for c in 0..w {
                    let mut acc = 0.0f64;
                    for i in 0..ci {
                        for ky in 0..3 {
                            for kx in 0..3 {
                                let (iy, ix) = (r as isize + ky - 1, c as isize + kx - 1);
                                if iy >= 0 && ix >= 0 && (iy as usize) < h && (ix as usize) < w {
                                    acc += weight
                                        [((o * ci + i) * 3 + ky as usize) * 3 + kx as usize]
                                        as f64
                                        * x.data[(i * h + iy as usize) * w + ix as usize] as f64;
                                }
                            }
                        }
                    }
                    out[(o * h + r) * w + c] = acc as f32;
                }
            }
        }
        out
    }

    #[test]
    fn matches_the_direct_convolution_on_odd_and_even_sizes() {
        for &(ci, co, h, w) in &[(3, 4, 9, 13), (5, 2, 1, 1), (8, 6, 40, 70), (2, 3, 2, 5)] {
            let weight = pseudo_random(co * ci * 9, 11);
            let x = FeatureMap::from_vec(ci, h, w, pseudo_random(ci * h * w, 12));
            let got = WinogradWeights::new(&weight, co, ci).forward(&x);
            let want = direct(&weight, &x, co);
            let err = got
                .data
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(err < 1e-5 * (ci as f32 * 9.0), "{ci}→{co} {h}×{w}: {err}");
        }
    }
}
