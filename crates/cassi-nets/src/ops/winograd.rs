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
                // SAFETY: blocks take disjoint tile rows ty0..ty1, so each
                // writes its own output rows 2·ty0 .. 2·ty1 (in every
                // channel); `out` stays borrowed until for_each returns.
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
        let mut scratch = take_scratch();
        let (v, m) = scratch.split(16 * ci * tiles, 16 * co * tiles);
        // Scratch of the transforms (see `input_tile_row`).
        let te = tw + 1;
        let mut d = vec![0.0f32; 8 * te];
        let mut r = vec![0.0f32; 8 * te];
        for i in 0..ci {
            let plane = x.channel(i);
            for ty in ty0..ty1 {
                // V[ξ][i][t0 .. t0 + tw] for the 16 ξ of this tile row.
                let t0 = (ty - ty0) * tw;
                input_tile_row(plane, w, ty, &mut d, &mut r, v, i * tiles + t0, ci * tiles);
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
        let mut s = vec![0.0f32; 8 * tw];
        let mut pixels = vec![0.0f32; 2 * tw];
        for o in 0..co {
            for ty in ty0..ty1 {
                let t0 = (ty - ty0) * tw;
                // SAFETY: output row 2·ty of channel `o` is in this block's
                // rows (this function's contract); `slice_mut` checks bounds.
                let row0 = unsafe { out.slice_mut((o * h + 2 * ty) * w, w) };
                let row1 = (2 * ty + 1 < h).then(|| {
                    // SAFETY: as row0; row 2·ty + 1 is taken only inside the image.
                    unsafe { out.slice_mut((o * h + 2 * ty + 1) * w, w) }
                });
                output_tile_row(
                    m,
                    o * tiles + t0,
                    co * tiles,
                    &mut s,
                    &mut pixels,
                    row0,
                    row1,
                );
            }
        }
        return_scratch(scratch);
    }
}

super::simd::avx2_dispatch! {
    /// The input transform of one channel's tile row `ty`: Bᵀ d B of each
    /// 4×4 patch (rows 2·ty − 1 … 2·ty + 2, zero outside the image), element
    /// ξ of tile t written to v[base + ξ·stride + t]. `d` and `r` are
    /// scratch of 8·(tw + 1) floats, tw = ⌈w/2⌉.
    #[allow(clippy::too_many_arguments)]
    fn input_tile_row(
        plane: &[f32],
        w: usize,
        ty: usize,
        d: &mut [f32],
        r: &mut [f32],
        v: &mut [f32],
        base: usize,
        stride: usize,
    ) {
        let h = plane.len() / w;
        let tw = w.div_ceil(2);
        let te = tw + 1;
        // Each input row, padded (column −1 … 2·tw) and split into even and
        // odd padded columns, e[t] = x[2t − 1], o[t] = x[2t]: every
        // transform below is then a contiguous loop.
        for a in 0..4 {
            let (e, o) = d[2 * a * te..(2 * a + 2) * te].split_at_mut(te);
            e.fill(0.0);
            o.fill(0.0);
            let y = (2 * ty + a) as isize - 1;
            if y >= 0 && (y as usize) < h {
                let row = &plane[y as usize * w..][..w];
                for (t, pair) in row.chunks_exact(2).enumerate() {
                    o[t] = pair[0];
                    e[t + 1] = pair[1];
                }
                if w % 2 == 1 {
                    o[w / 2] = row[w - 1];
                }
            }
        }
        // Bᵀ d over rows, Bᵀ = [1 0 −1 0; 0 1 1 0; 0 −1 1 0; 0 1 0 −1], on
        // the even and odd halves alike.
        let n = 2 * te;
        let (d0, rest) = d.split_at(n);
        let (d1, rest) = rest.split_at(n);
        let (d2, d3) = rest.split_at(n);
        let (r0, rest) = r.split_at_mut(n);
        let (r1, rest) = rest.split_at_mut(n);
        let (r2, r3) = rest.split_at_mut(n);
        for j in 0..n {
            r0[j] = d0[j] - d2[j];
            r1[j] = d1[j] + d2[j];
            r2[j] = d2[j] - d1[j];
            r3[j] = d1[j] - d3[j];
        }
        // (·) B over each tile's columns; with P the padded row: P[2t] −
        // P[2t+2], P[2t+1] + P[2t+2], P[2t+2] − P[2t+1], P[2t+1] − P[2t+3].
        for a in 0..4 {
            let (e, o) = r[2 * a * te..(2 * a + 2) * te].split_at(te);
            let (e0, e1, o0, o1) = (&e[..tw], &e[1..], &o[..tw], &o[1..]);
            let slab = |b: usize| base + (4 * a + b) * stride;
            let dst = &mut v[slab(0)..][..tw];
            for t in 0..tw {
                dst[t] = e0[t] - e1[t];
            }
            let dst = &mut v[slab(1)..][..tw];
            for t in 0..tw {
                dst[t] = o0[t] + e1[t];
            }
            let dst = &mut v[slab(2)..][..tw];
            for t in 0..tw {
                dst[t] = e1[t] - o0[t];
            }
            let dst = &mut v[slab(3)..][..tw];
            for t in 0..tw {
                dst[t] = o0[t] - o1[t];
            }
        }
    }
}

super::simd::avx2_dispatch! {
    /// The output transform of one output channel's tile row: Aᵀ M A,
    /// Aᵀ = [1 1 1 0; 0 1 −1 −1], with element ξ of tile t at
    /// m[base + ξ·stride + t]; writes output row 2·ty (`row0`) and, inside
    /// the image, 2·ty + 1 (`row1`). `s` (8·tw) and `pixels` (2·tw) are scratch.
    #[allow(clippy::too_many_arguments)]
    fn output_tile_row(
        m: &[f32],
        base: usize,
        stride: usize,
        s: &mut [f32],
        pixels: &mut [f32],
        row0: &mut [f32],
        row1: Option<&mut [f32]>,
    ) {
        let w = row0.len();
        let tw = w.div_ceil(2);
        let mm = |a: usize, b: usize| &m[base + (4 * a + b) * stride..][..tw];
        // Over rows first (s), then columns into even and odd pixels.
        for b in 0..4 {
            let (m0, m1, m2, m3) = (mm(0, b), mm(1, b), mm(2, b), mm(3, b));
            let (s0, s1) = s.split_at_mut(4 * tw);
            let (s0, s1) = (&mut s0[b * tw..][..tw], &mut s1[b * tw..][..tw]);
            for t in 0..tw {
                s0[t] = m0[t] + m1[t] + m2[t];
                s1[t] = m1[t] - m2[t] - m3[t];
            }
        }
        for (dy, dst) in std::iter::once(row0).chain(row1).enumerate() {
            let sr = &s[dy * 4 * tw..(dy + 1) * 4 * tw];
            let (c0, c1, c2, c3) = (&sr[..tw], &sr[tw..2 * tw], &sr[2 * tw..3 * tw], &sr[3 * tw..]);
            let (even, odd) = pixels.split_at_mut(tw);
            for t in 0..tw {
                even[t] = c0[t] + c1[t] + c2[t];
                odd[t] = c1[t] - c2[t] - c3[t];
            }
            for (t, pair) in dst.chunks_exact_mut(2).enumerate() {
                pair[0] = even[t];
                pair[1] = odd[t];
            }
            if w % 2 == 1 {
                dst[w - 1] = even[w / 2];
            }
        }
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
