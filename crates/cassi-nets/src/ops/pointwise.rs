//! Channel mixing, out[o, p] = bias[o] + Σ_c W[o, c] · x[c, p] for every
//! pixel p: the 1×1 convolutions and per-pixel Linear layers that carry
//! most of MST's arithmetic, and attention's A·V. Their shapes (8–224
//! channels, 4k–80k pixels) keep gemm at 18–36 GFLOP/s per core, most of
//! it packing; this kernel reads x where it lies and holds 6 output
//! channels × 16 pixels in 12 AVX registers, with the weights packed once
//! so the six broadcasts per input channel are adjacent. CPUs without
//! AVX2 + FMA take gemm.

use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
use super::activation::gelu_m256;
use super::activation::gelu_value;
use super::matmul::{Mat, SharedOut, matmul, matmul_into};

/// Output channels per register block.
const OB: usize = 6;
/// Pixels per register block (two 8-float vectors).
const PB: usize = 16;

/// What is applied to each output after the bias.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Activation {
    Identity,
    /// Exact (erf) GELU.
    Gelu,
}

/// A weight matrix (out × in, row-major) with its kernel packing.
pub(crate) struct MixWeights {
    weight: Vec<f32>,
    /// Groups of OB output channels, each (in × OB): packed[g][c][j] =
    /// W[g·OB + j, c], zero past the last output channel.
    packed: Vec<f32>,
    pub out_ch: usize,
    pub in_ch: usize,
}

impl MixWeights {
    pub fn new(weight: Vec<f32>, out_ch: usize, in_ch: usize) -> Self {
        assert_eq!(weight.len(), out_ch * in_ch, "mix weight size");
        let groups = out_ch.div_ceil(OB);
        let mut packed = vec![0.0; groups * in_ch * OB];
        for o in 0..out_ch {
            let (g, j) = (o / OB, o % OB);
            for c in 0..in_ch {
                packed[(g * in_ch + c) * OB + j] = weight[o * in_ch + c];
            }
        }
        Self {
            weight,
            packed,
            out_ch,
            in_ch,
        }
    }

    /// `out (out_ch × n) = act(W · x + bias)` for `x (in_ch × n)`, both
    /// row-major with rows n apart; every element of `out` is written.
    /// Parallel over pixel chunks.
    pub fn apply(
        &self,
        x: &[f32],
        n: usize,
        bias: Option<&[f32]>,
        act: Activation,
        out: &mut [f32],
    ) {
        self.run(x, n, bias, act, out, true)
    }

    /// [`apply`](Self::apply) in this thread only, for callers that are
    /// already one of many parallel tasks.
    pub fn apply_serial(
        &self,
        x: &[f32],
        n: usize,
        bias: Option<&[f32]>,
        act: Activation,
        out: &mut [f32],
    ) {
        self.run(x, n, bias, act, out, false)
    }

    fn run(
        &self,
        x: &[f32],
        n: usize,
        bias: Option<&[f32]>,
        act: Activation,
        out: &mut [f32],
        parallel: bool,
    ) {
        assert_eq!(x.len(), self.in_ch * n, "mix input size");
        assert_eq!(out.len(), self.out_ch * n, "mix output size");
        if let Some(b) = bias {
            assert_eq!(b.len(), self.out_ch, "mix bias size");
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            self.apply_blocked(x, n, bias, act, out, parallel);
            return;
        }
        self.apply_gemm(x, n, bias, act, out, parallel);
    }

    /// The portable path: gemm, then bias and activation.
    fn apply_gemm(
        &self,
        x: &[f32],
        n: usize,
        bias: Option<&[f32]>,
        act: Activation,
        out: &mut [f32],
        parallel: bool,
    ) {
        let w = Mat::rows(&self.weight, self.out_ch, self.in_ch, self.in_ch);
        let x = Mat::rows(x, self.in_ch, n, n);
        let finish_row = |(o, row): (usize, &mut [f32])| {
            let b = bias.map_or(0.0, |b| b[o]);
            for v in row {
                *v = finish(*v + b, act);
            }
        };
        if parallel {
            matmul(w, x, out);
            out.par_chunks_mut(n).enumerate().for_each(finish_row);
        } else {
            // SAFETY: `out` is exclusively borrowed for the call, single
            // threaded, and `matmul_into` bounds-checks out_ch × n against it.
            unsafe { matmul_into(w, x, SharedOut::new(out), 0, (n, 1), false) };
            out.chunks_mut(n).enumerate().for_each(finish_row);
        }
    }

    #[cfg(target_arch = "x86_64")]
    fn apply_blocked(
        &self,
        x: &[f32],
        n: usize,
        bias: Option<&[f32]>,
        act: Activation,
        out: &mut [f32],
        parallel: bool,
    ) {
        let shared = SharedOut::new(out);
        let chunk = if parallel { pixel_chunk(n) } else { n.max(1) };
        let task = |t: usize| {
            let p0 = t * chunk;
            let p1 = (p0 + chunk).min(n);
            // SAFETY: `apply` calls this only after detecting AVX2 and FMA
            // at run time; tasks write disjoint pixel ranges [p0, p1) of
            // every row, and `out` stays borrowed until they finish.
            unsafe { self.columns(x, n, p0, p1, bias, act, shared) };
        };
        if parallel {
            (0..n.div_ceil(chunk)).into_par_iter().for_each(task);
        } else {
            (0..n.div_ceil(chunk)).for_each(task);
        }
    }

    /// Pixels p0..p1 of every output row, in blocks whose packed input
    /// columns (in_ch × block) and outputs (out_ch × block) stay in L2.
    ///
    /// # Safety
    /// The CPU must have AVX2 and FMA; no other thread may write these
    /// pixels of `out` meanwhile.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn columns(
        &self,
        x: &[f32],
        n: usize,
        p0: usize,
        p1: usize,
        bias: Option<&[f32]>,
        act: Activation,
        out: SharedOut,
    ) {
        let (ci, co) = (self.in_ch, self.out_ch);
        // Pixels per block: (ci + co) × block floats ≈ 256 KiB, half of L2.
        let block = ((65536 / (ci + co)) / PB * PB).max(PB);
        let gelu = act == Activation::Gelu;
        let mut packed = PACKED_INPUT.with(|c| c.take());
        let mut b0 = p0;
        while b0 < p1 {
            let b1 = (b0 + block).min(p1);
            let strips = (b1 - b0) / PB;
            // Strip-major copy, packed[(s·ci + c)·PB + l] = x[c, b0 + s·PB + l]:
            // one sequential read per input row here (prefetch-friendly)
            // instead of ci rows at once inside the kernel.
            packed.resize(strips * ci * PB, 0.0);
            for c in 0..ci {
                let row = &x[c * n + b0..][..strips * PB];
                for (s, src) in row.chunks_exact(PB).enumerate() {
                    packed[(s * ci + c) * PB..][..PB].copy_from_slice(src);
                }
            }
            for g in 0..co.div_ceil(OB) {
                let w = &self.packed[g * ci * OB..(g + 1) * ci * OB];
                let outs = (co - g * OB).min(OB);
                for s in 0..strips {
                    let xs = &packed[s * ci * PB..(s + 1) * ci * PB];
                    // SAFETY: output rows g·OB .. g·OB + outs exist; the
                    // pixels b0 + s·PB .. + PB are this task's.
                    unsafe { block_6x16(w, xs, ci, b0 + s * PB, n, g * OB, outs, bias, gelu, out) };
                }
                for q in b0 + strips * PB..b1 {
                    for j in 0..outs {
                        let o = g * OB + j;
                        let mut acc = bias.map_or(0.0, |b| b[o]);
                        for c in 0..ci {
                            acc += w[c * OB + j] * x[c * n + q];
                        }
                        // SAFETY: pixel q of row o is this task's.
                        unsafe { out.slice_mut(o * n + q, 1)[0] = finish(acc, act) };
                    }
                }
            }
            b0 = b1;
        }
        PACKED_INPUT.with(|c| c.set(packed));
    }
}

thread_local! {
    /// Each worker's packed input block, kept between calls.
    static PACKED_INPUT: std::cell::Cell<Vec<f32>> = const { std::cell::Cell::new(Vec::new()) };
}

/// Pixels per parallel task: a few tasks per thread, a multiple of PB.
fn pixel_chunk(n: usize) -> usize {
    let tasks = rayon::current_num_threads().max(1) * 4;
    n.div_ceil(tasks).div_ceil(PB).max(1) * PB
}

#[inline(always)]
fn finish(v: f32, act: Activation) -> f32 {
    match act {
        Activation::Identity => v,
        Activation::Gelu => gelu_value(v),
    }
}

/// out[o0 + j, p .. p + 16] = bias + Σ_c w[c·OB + j] · xs[c·16 .. c·16 + 16]
/// for j < outs, with 12 accumulators (6 outputs × 2 vectors), GELU'd in
/// registers if `gelu`; `xs` is one packed strip (ci × 16), `out` has rows
/// n apart.
///
/// # Safety
/// AVX2 + FMA; `p + 16 ≤ n`; rows o0 .. o0 + outs of `out` exist and no
/// other thread writes these pixels.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn block_6x16(
    w: &[f32],
    xs: &[f32],
    ci: usize,
    p: usize,
    n: usize,
    o0: usize,
    outs: usize,
    bias: Option<&[f32]>,
    gelu: bool,
    out: SharedOut,
) {
    use std::arch::x86_64::*;
    assert!(w.len() == ci * OB && xs.len() == ci * PB && p + PB <= n);
    let mut acc = [[_mm256_setzero_ps(); 2]; OB];
    if let Some(b) = bias {
        for (j, a) in acc.iter_mut().enumerate().take(outs) {
            let v = _mm256_set1_ps(b[o0 + j]);
            *a = [v, v];
        }
    }
    let (xp, wp) = (xs.as_ptr(), w.as_ptr());
    for c in 0..ci {
        // SAFETY: c·PB + PB ≤ xs.len(); c·OB + OB ≤ w.len() (asserted).
        unsafe {
            let xa = _mm256_loadu_ps(xp.add(c * PB));
            let xb = _mm256_loadu_ps(xp.add(c * PB + 8));
            let wc = wp.add(c * OB);
            for (j, a) in acc.iter_mut().enumerate() {
                let wv = _mm256_broadcast_ss(&*wc.add(j));
                a[0] = _mm256_fmadd_ps(wv, xa, a[0]);
                a[1] = _mm256_fmadd_ps(wv, xb, a[1]);
            }
        }
    }
    if gelu {
        for a in acc.iter_mut().take(outs) {
            *a = [gelu_m256(a[0]), gelu_m256(a[1])];
        }
    }
    for (j, a) in acc.iter().enumerate().take(outs) {
        // SAFETY: row o0 + j exists; pixels p .. p + 16 are the caller's.
        unsafe {
            let dst = out.slice_mut((o0 + j) * n + p, PB);
            _mm256_storeu_ps(dst.as_mut_ptr(), a[0]);
            _mm256_storeu_ps(dst.as_mut_ptr().add(8), a[1]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::conv::tests::{max_abs_err, pseudo_random};

    fn naive(
        w: &[f32],
        x: &[f32],
        co: usize,
        ci: usize,
        n: usize,
        bias: Option<&[f32]>,
    ) -> Vec<f32> {
        let mut out = vec![0.0; co * n];
        for o in 0..co {
            for p in 0..n {
                let mut acc = bias.map_or(0.0, |b| b[o]) as f64;
                for c in 0..ci {
                    acc += w[o * ci + c] as f64 * x[c * n + p] as f64;
                }
                out[o * n + p] = acc as f32;
            }
        }
        out
    }

    #[test]
    fn both_paths_match_the_definition_for_awkward_shapes() {
        // Output counts around the 6-block, pixel counts around the 16-block
        // and the parallel chunking, and a GELU epilogue.
        for &(co, ci, n) in &[
            (1, 1, 1),
            (6, 3, 16),
            (7, 5, 37),
            (28, 28, 1000),
            (13, 112, 333),
        ] {
            let w = pseudo_random(co * ci, 21);
            let x = pseudo_random(ci * n, 22);
            let bias = pseudo_random(co, 23);
            let mix = MixWeights::new(w.clone(), co, ci);
            for (b, act) in [
                (None, Activation::Identity),
                (Some(&bias[..]), Activation::Gelu),
            ] {
                let mut want = naive(&w, &x, co, ci, n, b);
                if act == Activation::Gelu {
                    want.iter_mut().for_each(|v| *v = gelu_value(*v));
                }
                let mut got = vec![f32::NAN; co * n];
                mix.apply(&x, n, b, act, &mut got);
                let mut portable = vec![f32::NAN; co * n];
                mix.apply_gemm(&x, n, b, act, &mut portable, true);
                let mut serial = vec![f32::NAN; co * n];
                mix.apply_serial(&x, n, b, act, &mut serial);
                let mut portable_serial = vec![f32::NAN; co * n];
                mix.apply_gemm(&x, n, b, act, &mut portable_serial, false);
                for (name, g) in [
                    ("dispatched", &got),
                    ("portable", &portable),
                    ("serial", &serial),
                    ("portable serial", &portable_serial),
                ] {
                    let err = max_abs_err(g, &want);
                    assert!(err < 1e-5, "{name} {co}×{ci}×{n} {act:?}: {err}");
                }
            }
        }
    }
}
