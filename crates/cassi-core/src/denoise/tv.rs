//! Chambolle's (2004) dual projection algorithm for isotropic total-variation
//! (ROF) denoising: per band in 2-D ([`TvChambolle2d`]) and spatio-spectrally
//! in 3-D ([`TvChambolle3d`](super::TvChambolle3d)).
//!
//! # What is computed
//!
//! Both solve, approximately (a fixed number of iterations or the energy stop
//! below), the ROF problem `min_u ½‖u − f‖² + λ·TV(u)` with `λ = weight`
//! (the `strength` of [`Denoiser::denoise`]) and the isotropic TV
//! `TV(u) = Σ_x |K u (x)|₂`, `K` the forward differences (zero across the
//! last row/column/band), written as skimage writes it:
//!
//! ```text
//! p⁰ = 0
//! iteration i = 0, 1, …, max_iter − 1:
//!     d   = Kᵀ pⁱ            (d = 0 when i = 0; −divergence, skimage's `d`)
//!     out = f + d
//!     g   = K out,  |g| its pointwise Euclidean norm
//!     E   = (Σ d² + λ Σ |g|) / N        (f32, as skimage does it)
//!     pⁱ⁺¹ = (pⁱ − τ g) / (1 + (τ/λ) |g|)
//!     stop (returning this `out`) if i > 0 and |E_prev − E| < eps · E₀
//! return the `out` of the last iteration run
//! ```
//!
//! Note the returned `out` is computed at the start of the last iteration, so
//! `max_iter = 1` returns the input unchanged and `max_iter = n` applies
//! `n − 1` dual updates (the last one is never used, so it is not computed).
//!
//! # scikit-image correspondence
//!
//! [`TvChambolle2d`] is `skimage.restoration.denoise_tv_chambolle(cube,
//! weight, eps, max_num_iter, channel_axis=0)` on a float32 (bands, rows,
//! cols) cube: each band runs `_denoise_tv_chambolle_nd` on its own, with its
//! own stopping rule and iteration count ([`TvChambolle2d::iterations`]).
//! Every element-wise operation is the same f32 operation in the same order
//! (no FMA contraction, true divisions), so the iterates are bit-identical
//! to skimage's; only the two energy sums differ in summation order (numpy
//! sums f32 pairwise; here f32 lanes per row, rows in f64, rounded to f32),
//! which can only flip a stopping decision that sits within an f32 rounding of
//! its threshold. `τ = 1/4 = 1/(2·ndim)` as in skimage, and `τ/λ` is rounded
//! to f32 from f64 as numpy does. skimage raises on `weight = 0` and on
//! `max_num_iter = 0`; here `weight ≤ 0` (or NaN) and `max_iter ≤ 1` return the
//! input unchanged (the ROF solution at λ = 0 is `f`).
//!
//! [`TvChambolle3d`](super::TvChambolle3d) with spectral weight μ = 1 is
//! `denoise_tv_chambolle(cube, weight, eps, max_num_iter)` with
//! `channel_axis=None` (3-D TV, one global stopping rule), bit-identical too.
//!
//! # Step sizes
//!
//! Writing `K = (w_a D_a)_a` (per-axis weights `w_a`), ‖D_a‖² < 4, so
//! ‖K‖² < 4 Σ w_a². Chambolle (2004) proves convergence for τ ≤ 1/‖K‖² and
//! observes it up to 1/4 in 2-D; the projected-gradient form of the same
//! dual iteration converges for τ < 2/‖K‖², whose safe version with the bound
//! above is τ = 1/(2 Σ w_a²) — skimage's `1/(2·ndim)` when all w_a = 1. The
//! 3-D variant applies the same rule to its weighted gradient
//! `(μ D_band, D_row, D_col)`: `τ = 1 / (2 (2 + μ²))`, i.e. 1/6 at μ = 1
//! (skimage's 3-D value) and 1/4 at μ = 0 (the 2-D value, so μ = 0 reproduces
//! the 2-D iterates exactly). Scaling τ with μ² keeps τ‖K‖² inside the same
//! guaranteed range for every μ; a fixed 1/6 would leave it for μ > 1.
//!
//! # Speed
//!
//! One iteration is one pass, row by row: the row below gets its divergence
//! and `out` while the current row gets its gradient, norm, dual update and
//! both energy terms. The first iteration (p = 0) only computes the gradient
//! of the input; the last only forms `out`, in place. Inner loops run over
//! contiguous rows in blocks of 8 lanes (auto-vectorised, no bounds checks);
//! each row kernel is compiled three times, for baseline x86-64 (SSE2), AVX
//! and AVX-512 (`crate::simd`), and the widest copy the CPU has is used
//! (runtime detection; no FMA, so every copy gives bit-identical results). 2-D bands run in parallel
//! (rayon), a contiguous run of bands per worker, each worker with its own
//! scratch (`out`, `p_row`, `p_col`: 3 band-sized buffers) so a band's whole
//! working set (with the band itself, 4 × rows × cols f32) stays in L2 across
//! its iterations. Scratch is sized on the first call and reused while the
//! shape and thread count repeat: no allocation per call once warm.

use rayon::prelude::*;

use crate::Cube;
use crate::denoise::Denoiser;

/// Iteration controls shared by the TV denoisers. `Default` is skimage's
/// (`max_num_iter = 200`, `eps = 2e-4`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TvChambolleParams {
    /// At most this many iterations (skimage `max_num_iter`); the output is
    /// the iterate of the last one, so ≤ 1 returns the input.
    pub max_iter: usize,
    /// Stop when `|E_prev − E| < eps · E₀` (skimage `eps`); 0 never stops early.
    pub eps: f32,
}

impl Default for TvChambolleParams {
    fn default() -> Self {
        Self {
            max_iter: 200,
            eps: 2e-4,
        }
    }
}

/// Block width of the vectorised inner loops (two SSE registers, one AVX).
pub(super) const LANES: usize = 8;

/// The two constants of the dual update, rounded to f32 as numpy does:
/// `p -= tau * g` uses `f32(τ)`, `norm *= tau / weight` uses `f32(τ/λ)`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Step {
    pub(super) tau: f32,
    pub(super) tau_over_weight: f32,
}

impl Step {
    pub(super) fn new(tau: f64, weight: f32) -> Self {
        Self {
            tau: tau as f32,
            tau_over_weight: (tau / weight as f64) as f32,
        }
    }
}

/// skimage's energy in f32: `E = Σd²; E += λ·Σ|g|; E /= N`.
#[inline]
pub(super) fn energy(sum_d2: f64, sum_norm: f64, weight: f32, n: usize) -> f32 {
    let e = sum_d2 as f32 + weight * sum_norm as f32;
    e / n as f32
}

/// skimage's stopping bookkeeping.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct Stopper {
    e_init: f32,
    e_prev: f32,
}

impl Stopper {
    /// True when iteration `i` with energy `e` is the last one.
    #[inline]
    pub(super) fn stop(&mut self, i: usize, e: f32, eps: f32) -> bool {
        if i == 0 {
            self.e_init = e;
            self.e_prev = e;
            false
        } else if (self.e_prev - e).abs() < eps * self.e_init {
            true
        } else {
            self.e_prev = e;
            false
        }
    }
}

pub(super) use crate::simd::{Simd, kernel};

#[inline(always)]
pub(super) fn lanes_sum(a: &[f32; LANES]) -> f64 {
    a.iter().map(|&v| v as f64).sum()
}

/// The dual update of one pixel in numpy's operation order: new (p_a, p_b)
/// and the gradient norm.
#[inline(always)]
fn dual2(pa: f32, pb: f32, ga: f32, gb: f32, k: Step) -> (f32, f32, f32) {
    let nrm = (ga * ga + gb * gb).sqrt();
    let den = nrm * k.tau_over_weight + 1.0;
    ((pa - k.tau * ga) / den, (pb - k.tau * gb) / den, nrm)
}

// ---------------------------------------------------------------------------
// 2-D row kernels. Within a band: p0 = dual of the row difference (axis 0),
// p1 = dual of the column difference (axis 1). Rows have length w ≥ 1.
// ---------------------------------------------------------------------------

/// `out = f + Kᵀp` for one row; `p0_up` is p0 of the row above (zeros for
/// row 0). Returns Σd² of the row.
#[inline(always)]
fn out2_body(f: &[f32], p0: &[f32], p1: &[f32], p0_up: &[f32], out: &mut [f32]) -> f64 {
    let w = f.len();
    let (p0, p1, p0_up, out) = (&p0[..w], &p1[..w], &p0_up[..w], &mut out[..w]);
    let t = -(p0[0] + p1[0]) + p0_up[0];
    out[0] = f[0] + t;
    let mut d2 = (t * t) as f64;
    if w < 2 {
        return d2;
    }
    let mv = (w - 1) / LANES * LANES; // vector body: columns 1..1+mv
    let mut acc = [0f32; LANES];
    let it = f[1..1 + mv]
        .chunks_exact(LANES)
        .zip(p0[1..1 + mv].chunks_exact(LANES))
        .zip(p1[1..1 + mv].chunks_exact(LANES))
        .zip(p1[..mv].chunks_exact(LANES))
        .zip(p0_up[1..1 + mv].chunks_exact(LANES))
        .zip(out[1..1 + mv].chunks_exact_mut(LANES));
    for (((((f, p0), p1), p1l), p0u), o) in it {
        for l in 0..LANES {
            let t = (-(p0[l] + p1[l]) + p0u[l]) + p1l[l];
            o[l] = f[l] + t;
            acc[l] += t * t;
        }
    }
    d2 += lanes_sum(&acc);
    for c in 1 + mv..w {
        let t = (-(p0[c] + p1[c]) + p0_up[c]) + p1[c - 1];
        out[c] = f[c] + t;
        d2 += (t * t) as f64;
    }
    d2
}

/// `fo ← fo + Kᵀp` for one row, in place (the last iteration).
#[inline(always)]
fn out2_inplace_body(fo: &mut [f32], p0: &[f32], p1: &[f32], p0_up: &[f32]) {
    let w = fo.len();
    let (p0, p1, p0_up) = (&p0[..w], &p1[..w], &p0_up[..w]);
    fo[0] += -(p0[0] + p1[0]) + p0_up[0];
    if w < 2 {
        return;
    }
    let mv = (w - 1) / LANES * LANES;
    let it = fo[1..1 + mv]
        .chunks_exact_mut(LANES)
        .zip(p0[1..1 + mv].chunks_exact(LANES))
        .zip(p1[1..1 + mv].chunks_exact(LANES))
        .zip(p1[..mv].chunks_exact(LANES))
        .zip(p0_up[1..1 + mv].chunks_exact(LANES));
    for ((((o, p0), p1), p1l), p0u) in it {
        for l in 0..LANES {
            o[l] += (-(p0[l] + p1[l]) + p0u[l]) + p1l[l];
        }
    }
    for c in 1 + mv..w {
        fo[c] += (-(p0[c] + p1[c]) + p0_up[c]) + p1[c - 1];
    }
}

/// Dual update of a row from known `out` rows: `g0 = o_dn − o` (pass
/// `o_dn = o` for the last row: g0 = 0), `g1` the column difference. With
/// `FIRST` the old duals are taken as 0 (not read). Returns Σ|g|.
#[inline(always)]
fn upd2_body<const FIRST: bool>(
    o: &[f32],
    o_dn: &[f32],
    p0: &mut [f32],
    p1: &mut [f32],
    k: Step,
) -> f64 {
    let w = o.len();
    let (o_dn, p0, p1) = (&o_dn[..w], &mut p0[..w], &mut p1[..w]);
    let mut sn = 0f64;
    let mv = (w - 1) / LANES * LANES; // columns 0..mv have a right neighbour
    let mut acc = [0f32; LANES];
    let it = o[..mv]
        .chunks_exact(LANES)
        .zip(o[1..1 + mv].chunks_exact(LANES))
        .zip(o_dn[..mv].chunks_exact(LANES))
        .zip(p0[..mv].chunks_exact_mut(LANES))
        .zip(p1[..mv].chunks_exact_mut(LANES));
    for ((((o, or), od), p0), p1) in it {
        for l in 0..LANES {
            let (a0, a1) = if FIRST { (0.0, 0.0) } else { (p0[l], p1[l]) };
            let (a, b, n) = dual2(a0, a1, od[l] - o[l], or[l] - o[l], k);
            p0[l] = a;
            p1[l] = b;
            acc[l] += n;
        }
    }
    sn += lanes_sum(&acc);
    for c in mv..w {
        let g1 = if c + 1 < w { o[c + 1] - o[c] } else { 0.0 };
        let (a0, a1) = if FIRST { (0.0, 0.0) } else { (p0[c], p1[c]) };
        let (a, b, n) = dual2(a0, a1, o_dn[c] - o[c], g1, k);
        p0[c] = a;
        p1[c] = b;
        sn += n as f64;
    }
    sn
}

/// The fused step of a full pass: `out` of row r+1 (`x`) and the dual update
/// of row r (`y`), whose old p0 is the `p0_up` of row r+1 (read before it is
/// overwritten). Returns (Σd² of row r+1, Σ|g| of row r).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn fused2_body(
    fx: &[f32],
    p0x: &[f32],
    p1x: &[f32],
    ox: &mut [f32],
    oy: &[f32],
    p0y: &mut [f32],
    p1y: &mut [f32],
    k: Step,
) -> (f64, f64) {
    let w = fx.len();
    let (p0x, p1x, ox, oy, p0y, p1y) = (
        &p0x[..w],
        &p1x[..w],
        &mut ox[..w],
        &oy[..w],
        &mut p0y[..w],
        &mut p1y[..w],
    );
    // Columns are independent within this step. The vector body takes
    // columns 1..1+mv (both column neighbours exist); column 0 and the tail go
    // through the scalar loop.
    let mv = w.saturating_sub(2) / LANES * LANES;
    let (mut ad, mut an) = ([0f32; LANES], [0f32; LANES]);
    if mv > 0 {
        let it = fx[1..1 + mv]
            .chunks_exact(LANES)
            .zip(p0x[1..1 + mv].chunks_exact(LANES))
            .zip(p1x[1..1 + mv].chunks_exact(LANES))
            .zip(p1x[..mv].chunks_exact(LANES))
            .zip(ox[1..1 + mv].chunks_exact_mut(LANES))
            .zip(oy[1..1 + mv].chunks_exact(LANES))
            .zip(oy[2..2 + mv].chunks_exact(LANES))
            .zip(p0y[1..1 + mv].chunks_exact_mut(LANES))
            .zip(p1y[1..1 + mv].chunks_exact_mut(LANES));
        for ((((((((f, p0n), p1n), p1l), on), oc), or), p0c), p1c) in it {
            for l in 0..LANES {
                let t = (-(p0n[l] + p1n[l]) + p0c[l]) + p1l[l];
                let o = f[l] + t;
                on[l] = o;
                ad[l] += t * t;
                let (a, b, n) = dual2(p0c[l], p1c[l], o - oc[l], or[l] - oc[l], k);
                p0c[l] = a;
                p1c[l] = b;
                an[l] += n;
            }
        }
    }
    let mut d2 = lanes_sum(&ad);
    let mut sn = lanes_sum(&an);
    for c in std::iter::once(0).chain(1 + mv..w) {
        let mut t = -(p0x[c] + p1x[c]) + p0y[c];
        if c > 0 {
            t += p1x[c - 1];
        }
        let o = fx[c] + t;
        ox[c] = o;
        d2 += (t * t) as f64;
        let g1 = if c + 1 < w { oy[c + 1] - oy[c] } else { 0.0 };
        let (a, b, n) = dual2(p0y[c], p1y[c], o - oy[c], g1, k);
        p0y[c] = a;
        p1y[c] = b;
        sn += n as f64;
    }
    (d2, sn)
}

kernel!(out2, out2_port, out2_avx,
    (f: &[f32], p0: &[f32], p1: &[f32], p0_up: &[f32], out: &mut [f32]) -> f64
    = out2_body(f, p0, p1, p0_up, out));
kernel!(out2_inplace, out2_inplace_port, out2_inplace_avx,
    (fo: &mut [f32], p0: &[f32], p1: &[f32], p0_up: &[f32]) -> ()
    = out2_inplace_body(fo, p0, p1, p0_up));
kernel!(upd2_first, upd2_first_port, upd2_first_avx,
    (o: &[f32], o_dn: &[f32], p0: &mut [f32], p1: &mut [f32], k: Step) -> f64
    = upd2_body::<true>(o, o_dn, p0, p1, k));
kernel!(upd2, upd2_port, upd2_avx,
    (o: &[f32], o_dn: &[f32], p0: &mut [f32], p1: &mut [f32], k: Step) -> f64
    = upd2_body::<false>(o, o_dn, p0, p1, k));
kernel!(fused2, fused2_port, fused2_avx,
    (fx: &[f32], p0x: &[f32], p1x: &[f32], ox: &mut [f32], oy: &[f32],
     p0y: &mut [f32], p1y: &mut [f32], k: Step) -> (f64, f64)
    = fused2_body(fx, p0x, p1x, ox, oy, p0y, p1y, k));

/// Row r of a (rows, w) band, and the row below it (row r itself for the
/// last row, which makes the row difference 0).
#[inline]
pub(super) fn row_and_below(a: &[f32], r: usize, w: usize) -> (&[f32], &[f32]) {
    let row = &a[r * w..(r + 1) * w];
    let below = a.get((r + 1) * w..(r + 2) * w).unwrap_or(row);
    (row, below)
}

/// Everything one 2-D band solve needs besides its buffers.
#[derive(Clone, Copy)]
struct Band2d<'a> {
    w: usize,
    weight: f32,
    k: Step,
    params: &'a TvChambolleParams,
    zeros: &'a [f32],
    simd: Simd,
}

impl Band2d<'_> {
    /// skimage's `_denoise_tv_chambolle_nd` on one band, in place (`band`
    /// holds f on entry). `o`, `p0`, `p1` are band-sized scratch. Needs
    /// `max_iter ≥ 2`. Returns the number of iterations run.
    fn solve(&self, band: &mut [f32], o: &mut [f32], p0: &mut [f32], p1: &mut [f32]) -> usize {
        let (w, s) = (self.w, self.simd);
        let h = band.len() / w;
        let mut stop = Stopper::default();
        // i = 0: out = f, p¹ = (0 − τ K f) / (1 + τ/λ |K f|).
        let mut sn = 0f64;
        for r in 0..h {
            let (row, below) = row_and_below(band, r, w);
            let rr = r * w..(r + 1) * w;
            sn += upd2_first(s, row, below, &mut p0[rr.clone()], &mut p1[rr], self.k);
        }
        stop.stop(0, energy(0.0, sn, self.weight, band.len()), self.params.eps);
        let mut i = 1;
        loop {
            if i + 1 >= self.params.max_iter {
                self.final_pass(band, p0, p1);
                return i + 1;
            }
            let (d2, sn) = self.full_pass(band, o, p0, p1);
            let e = energy(d2, sn, self.weight, band.len());
            if stop.stop(i, e, self.params.eps) {
                band.copy_from_slice(o);
                return i + 1;
            }
            i += 1;
        }
    }

    /// `o ← f + Kᵀp`, `p ← update(K o)`. Returns (Σd², Σ|g|).
    fn full_pass(&self, f: &[f32], o: &mut [f32], p0: &mut [f32], p1: &mut [f32]) -> (f64, f64) {
        let (w, s) = (self.w, self.simd);
        let h = f.len() / w;
        let mut d2 = out2(s, &f[..w], &p0[..w], &p1[..w], self.zeros, &mut o[..w]);
        let mut sn = 0f64;
        for r in 0..h - 1 {
            let (oy, ox) = o[r * w..(r + 2) * w].split_at_mut(w);
            let (p0y, p0x) = p0[r * w..(r + 2) * w].split_at_mut(w);
            let (p1y, p1x) = p1[r * w..(r + 2) * w].split_at_mut(w);
            let fx = &f[(r + 1) * w..(r + 2) * w];
            let (a, b) = fused2(s, fx, p0x, p1x, ox, oy, p0y, p1y, self.k);
            d2 += a;
            sn += b;
        }
        let last = (h - 1) * w..h * w;
        let ol = &o[last.clone()];
        sn += upd2(s, ol, ol, &mut p0[last.clone()], &mut p1[last], self.k);
        (d2, sn)
    }

    /// `band ← band + Kᵀp` (the last iteration's `out`).
    fn final_pass(&self, band: &mut [f32], p0: &[f32], p1: &[f32]) {
        let w = self.w;
        for (r, row) in band.chunks_exact_mut(w).enumerate() {
            let up = if r == 0 {
                self.zeros
            } else {
                &p0[(r - 1) * w..r * w]
            };
            let rr = r * w..(r + 1) * w;
            out2_inplace(self.simd, row, &p0[rr.clone()], &p1[rr], up);
        }
    }
}

/// Scratch of [`tv_chambolle_2d`]: per worker, three band-sized buffers.
/// Sized on first use; reused (no allocation) while the band shape and the
/// worker count repeat.
#[derive(Debug, Default, Clone)]
pub struct TvScratch2d {
    band_len: usize,
    cols: usize,
    workers: usize,
    buf: Vec<f32>,
    zeros: Vec<f32>,
    iterations: Vec<usize>,
    portable_only: bool,
}

impl TvScratch2d {
    pub fn new() -> Self {
        Self::default()
    }

    /// Iterations run per band by the last call (skimage's loop count).
    pub fn iterations(&self) -> &[usize] {
        &self.iterations
    }

    /// Use only the baseline (SSE2) kernels, never the AVX copies. Both give
    /// bit-identical results; this is for tests and benchmarks.
    pub fn set_portable_only(&mut self, on: bool) {
        self.portable_only = on;
    }

    fn prepare(&mut self, bands: usize, rows: usize, cols: usize, workers: usize) {
        let band_len = rows * cols;
        if self.band_len != band_len || self.cols != cols || self.workers != workers {
            self.band_len = band_len;
            self.cols = cols;
            self.workers = workers;
            self.buf = vec![0.0; 3 * band_len * workers];
            self.zeros = vec![0.0; cols];
        }
        if self.iterations.len() != bands {
            self.iterations.resize(bands, 0);
        }
    }
}

/// Isotropic 2-D Chambolle TV denoising of every band of `cube`, in place:
/// skimage `denoise_tv_chambolle(cube, weight, eps, max_num_iter,
/// channel_axis=0)` in float32 (see the module docs). Bands run in parallel,
/// each with its own stopping rule; per-band iteration counts are left in
/// `scratch.iterations()`. `weight ≤ 0` (or NaN) leaves the cube unchanged.
pub fn tv_chambolle_2d(
    cube: &mut Cube,
    weight: f32,
    params: &TvChambolleParams,
    scratch: &mut TvScratch2d,
) {
    let (bands, rows, cols) = cube.shape();
    let n = rows * cols;
    // weight ≤ 0 / NaN: the identity (0 iterations); max_iter ≤ 1: skimage
    // returns its input.
    let trivial = n == 0 || weight.is_nan() || weight <= 0.0 || params.max_iter <= 1;
    if trivial {
        let it = if n > 0 && weight > 0.0 {
            params.max_iter
        } else {
            0
        };
        scratch.iterations.clear();
        scratch.iterations.resize(bands, it);
        return;
    }
    let workers = rayon::current_num_threads().clamp(1, bands);
    scratch.prepare(bands, rows, cols, workers);
    let per = bands.div_ceil(workers);
    let solver = Band2d {
        w: cols,
        weight,
        k: Step::new(0.25, weight),
        params,
        zeros: &scratch.zeros,
        simd: Simd::detect(scratch.portable_only),
    };
    cube.as_mut_slice()
        .par_chunks_mut(per * n)
        .zip(scratch.buf.par_chunks_mut(3 * n))
        .zip(scratch.iterations.par_chunks_mut(per))
        .for_each(|((bands_data, buf), iters)| {
            let (o, rest) = buf.split_at_mut(n);
            let (p0, p1) = rest.split_at_mut(n);
            for (band, it) in bands_data.chunks_exact_mut(n).zip(iters.iter_mut()) {
                *it = solver.solve(band, o, p0, p1);
            }
        });
}

/// Per-band isotropic 2-D Chambolle TV denoiser (skimage
/// `denoise_tv_chambolle(…, channel_axis=0)`); `strength` is the weight λ.
#[derive(Debug, Default, Clone)]
pub struct TvChambolle2d {
    pub params: TvChambolleParams,
    scratch: TvScratch2d,
}

impl TvChambolle2d {
    pub fn new(params: TvChambolleParams) -> Self {
        Self {
            params,
            scratch: TvScratch2d::new(),
        }
    }

    /// Iterations run per band by the last call.
    pub fn iterations(&self) -> &[usize] {
        self.scratch.iterations()
    }
}

impl Denoiser for TvChambolle2d {
    fn denoise(&mut self, cube: &mut Cube, strength: f32) {
        tv_chambolle_2d(cube, strength, &self.params, &mut self.scratch);
    }

    fn name(&self) -> String {
        "tv-chambolle-2d".into()
    }
}

/// Isotropic 2-D TV summed over bands: Σ_b Σ_x sqrt((Δ_row u)² + (Δ_col u)²),
/// forward differences, zero across the last row/column (skimage's `K`), in f64.
pub fn isotropic_tv_2d(cube: &Cube) -> f64 {
    isotropic_tv_3d(cube, 0.0)
}

/// Isotropic spatio-spectral TV Σ sqrt(μ² (Δ_band u)² + (Δ_row u)² +
/// (Δ_col u)²), forward differences, zero across the last band/row/column, in f64.
pub fn isotropic_tv_3d(cube: &Cube, spectral_weight: f32) -> f64 {
    let (l, h, w) = cube.shape();
    let mu = spectral_weight as f64;
    let mut tv = 0f64;
    for b in 0..l {
        for r in 0..h {
            for c in 0..w {
                let u = cube.get(b, r, c) as f64;
                let diff = |v: f32| v as f64 - u;
                let gb = if b + 1 < l {
                    mu * diff(cube.get(b + 1, r, c))
                } else {
                    0.0
                };
                let gr = if r + 1 < h {
                    diff(cube.get(b, r + 1, c))
                } else {
                    0.0
                };
                let gc = if c + 1 < w {
                    diff(cube.get(b, r, c + 1))
                } else {
                    0.0
                };
                tv += (gb * gb + gr * gr + gc * gc).sqrt();
            }
        }
    }
    tv
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Rng;
    use crate::denoise::tv3d::{TvChambolle3d, TvScratch3d, tv_chambolle_3d};

    fn noisy(l: usize, h: usize, w: usize, seed: u64) -> Cube {
        let mut rng = Rng::new(seed);
        let mut c = Cube::zeros(l, h, w);
        for b in 0..l {
            for r in 0..h {
                for col in 0..w {
                    let s = 0.3 + 0.4 * (((r / 5 + col / 7 + b) % 2) as f64);
                    c.set(b, r, col, (s + 0.15 * rng.normal()) as f32);
                }
            }
        }
        c
    }

    fn p(max_iter: usize, eps: f32) -> TvChambolleParams {
        TvChambolleParams { max_iter, eps }
    }

    fn tv2(c: &mut Cube, weight: f32, params: TvChambolleParams) -> Vec<usize> {
        let mut s = TvScratch2d::new();
        tv_chambolle_2d(c, weight, &params, &mut s);
        s.iterations().to_vec()
    }

    fn tv3(c: &mut Cube, weight: f32, mu: f32, params: TvChambolleParams) -> usize {
        let mut s = TvScratch3d::new();
        tv_chambolle_3d(c, weight, mu, &params, &mut s);
        s.iterations()
    }

    /// skimage's `_denoise_tv_chambolle_nd` written out plainly on one
    /// volume of shape `dims` (ndim = dims.len()), with per-axis gradient
    /// weights `wa` (all 1 in skimage). Energies summed in f64.
    fn naive(
        img: &[f32],
        dims: &[usize],
        wa: &[f32],
        tau: f64,
        weight: f32,
        params: TvChambolleParams,
    ) -> (Vec<f32>, usize) {
        let nd = dims.len();
        let len = img.len();
        let mut stride = vec![1usize; nd];
        for a in (0..nd - 1).rev() {
            stride[a] = stride[a + 1] * dims[a + 1];
        }
        let coord = |x: usize, a: usize| (x / stride[a]) % dims[a];
        let k = Step::new(tau, weight);
        let mut p = vec![vec![0f32; len]; nd];
        let mut g = vec![vec![0f32; len]; nd];
        let mut out = img.to_vec();
        let mut stop = Stopper::default();
        let mut i = 0;
        while i < params.max_iter {
            let mut d = vec![0f32; len];
            if i > 0 {
                for x in 0..len {
                    let mut s = wa[0] * p[0][x];
                    for a in 1..nd {
                        s += wa[a] * p[a][x];
                    }
                    d[x] = -s;
                }
                for a in 0..nd {
                    for x in 0..len {
                        if coord(x, a) >= 1 {
                            d[x] += wa[a] * p[a][x - stride[a]];
                        }
                    }
                }
                for x in 0..len {
                    out[x] = img[x] + d[x];
                }
            }
            let sd2: f64 = d.iter().map(|&v| (v * v) as f64).sum();
            for a in 0..nd {
                for x in 0..len {
                    g[a][x] = if coord(x, a) + 1 < dims[a] {
                        wa[a] * (out[x + stride[a]] - out[x])
                    } else {
                        0.0
                    };
                }
            }
            let mut sn = 0f64;
            for x in 0..len {
                let mut q = g[0][x] * g[0][x];
                for ga in g.iter().skip(1) {
                    q += ga[x] * ga[x];
                }
                let nrm = q.sqrt();
                sn += nrm as f64;
                let den = nrm * k.tau_over_weight + 1.0;
                for a in 0..nd {
                    p[a][x] = (p[a][x] - k.tau * g[a][x]) / den;
                }
            }
            if stop.stop(i, energy(sd2, sn, weight, len), params.eps) {
                i += 1;
                break;
            }
            i += 1;
        }
        (out, i)
    }

    fn max_diff(a: &[f32], b: &[f32]) -> f32 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max)
    }

    #[test]
    fn matches_plain_port_on_odd_shapes() {
        let shapes = [
            (1, 1, 1),
            (2, 1, 9),
            (2, 9, 1),
            (1, 2, 2),
            (3, 3, 10),
            (2, 7, 17),
            (1, 5, 26),
            (2, 12, 33),
        ];
        for (si, &(l, h, w)) in shapes.iter().enumerate() {
            let x = noisy(l, h, w, 10 + si as u64);
            for &(weight, n, eps) in &[(0.1, 2, 2e-4), (0.3, 5, 2e-4), (0.05, 60, 1e-3)] {
                let prm = p(n, eps);
                // 2-D, per band
                let mut got = x.clone();
                let iters = tv2(&mut got, weight, prm);
                for (b, &ib) in iters.iter().enumerate() {
                    let (want, wi) = naive(x.band(b), &[h, w], &[1.0, 1.0], 0.25, weight, prm);
                    let d = max_diff(got.band(b), &want);
                    assert!(d <= 1e-6, "2d {l}x{h}x{w} w={weight} n={n} band {b}: {d:e}");
                    assert_eq!(ib, wi, "2d {l}x{h}x{w} band {b} iterations");
                }
                // 3-D with several spectral weights
                for mu in [1.0f32, 0.5, 2.0] {
                    let mut got = x.clone();
                    let it = tv3(&mut got, weight, mu, prm);
                    let tau = 1.0 / (2.0 * (2.0 + mu as f64 * mu as f64));
                    let (want, wi) =
                        naive(x.as_slice(), &[l, h, w], &[mu, 1.0, 1.0], tau, weight, prm);
                    let d = max_diff(got.as_slice(), &want);
                    assert!(d <= 1e-6, "3d {l}x{h}x{w} mu={mu} w={weight} n={n}: {d:e}");
                    assert_eq!(it, wi, "3d {l}x{h}x{w} mu={mu} iterations");
                }
            }
        }
    }

    #[test]
    fn constant_cube_is_unchanged() {
        let c = Cube::from_vec(3, 8, 11, vec![0.625; 3 * 8 * 11]).unwrap();
        for n in [2, 5, 200] {
            let mut a = c.clone();
            tv2(&mut a, 0.2, p(n, 2e-4));
            assert_eq!(a, c);
            let mut a = c.clone();
            tv3(&mut a, 0.2, 1.0, p(n, 2e-4));
            assert_eq!(a, c);
        }
    }

    #[test]
    fn zero_weight_or_trivial_iterations_leave_the_cube_unchanged() {
        let x = noisy(2, 9, 13, 3);
        for (weight, n) in [(0.0, 5), (-1.0, 5), (f32::NAN, 5), (0.3, 0), (0.3, 1)] {
            let mut a = x.clone();
            tv2(&mut a, weight, p(n, 2e-4));
            assert_eq!(a, x, "2d weight {weight} max_iter {n}");
            let mut a = x.clone();
            tv3(&mut a, weight, 1.0, p(n, 2e-4));
            assert_eq!(a, x, "3d weight {weight} max_iter {n}");
        }
    }

    /// Primal ROF objective ½‖u − f‖² + λ·TV(u).
    fn rof(u: &Cube, f: &Cube, weight: f32, mu: Option<f32>) -> f64 {
        let fid: f64 = u
            .as_slice()
            .iter()
            .zip(f.as_slice())
            .map(|(&a, &b)| 0.5 * (a as f64 - b as f64).powi(2))
            .sum();
        let tv = match mu {
            None => isotropic_tv_2d(u),
            Some(m) => isotropic_tv_3d(u, m),
        };
        fid + weight as f64 * tv
    }

    #[test]
    fn tv_and_rof_objective_decrease_with_iterations_2d() {
        let x = noisy(2, 24, 31, 5);
        let weight = 0.15;
        let tv0 = isotropic_tv_2d(&x);
        let (mut prev_tv, mut prev_rof) = (tv0, rof(&x, &x, weight, None));
        for n in [2, 3, 5, 10, 20, 50, 200] {
            let mut u = x.clone();
            tv2(&mut u, weight, p(n, 0.0));
            let (t, e) = (isotropic_tv_2d(&u), rof(&u, &x, weight, None));
            assert!(t < tv0, "n={n}: TV {t} not below input {tv0}");
            assert!(t <= prev_tv * (1.0 + 1e-3), "n={n}: TV {t} > {prev_tv}");
            assert!(e <= prev_rof * (1.0 + 1e-4), "n={n}: ROF {e} > {prev_rof}");
            (prev_tv, prev_rof) = (t, e);
        }
        assert!(prev_tv < 0.5 * tv0, "{prev_tv} vs {tv0}");
    }

    #[test]
    fn three_d_reduces_3d_tv_and_converges_for_any_spectral_weight() {
        let x = noisy(6, 16, 19, 8);
        let weight = 0.15;
        for mu in [0.5f32, 1.0, 2.0, 4.0] {
            let tv0 = isotropic_tv_3d(&x, mu);
            let mut prev = rof(&x, &x, weight, Some(mu));
            for n in [2, 5, 20, 100, 400] {
                let mut u = x.clone();
                tv3(&mut u, weight, mu, p(n, 0.0));
                assert!(u.check_finite("tv3").is_ok());
                let e = rof(&u, &x, weight, Some(mu));
                assert!(isotropic_tv_3d(&u, mu) < tv0, "mu={mu} n={n}");
                assert!(e <= prev * (1.0 + 1e-4), "mu={mu} n={n}: ROF {e} > {prev}");
                prev = e;
            }
        }
        // μ > 0 smooths spectra more than the 2-D TV at the same weight.
        let (mut a, mut b) = (x.clone(), x.clone());
        tv2(&mut a, weight, p(50, 0.0));
        tv3(&mut b, weight, 1.0, p(50, 0.0));
        assert!(isotropic_tv_3d(&b, 1.0) < isotropic_tv_3d(&a, 1.0));
    }

    #[test]
    fn spectral_weight_zero_gives_the_2d_iterates() {
        let x = noisy(4, 13, 21, 9);
        for n in [2, 3, 7, 30] {
            let (mut a, mut b) = (x.clone(), x.clone());
            tv2(&mut a, 0.2, p(n, 0.0));
            assert_eq!(tv3(&mut b, 0.2, 0.0, p(n, 0.0)), n);
            assert_eq!(a, b, "max_iter {n}");
        }
    }

    #[test]
    fn scratch_reuse_and_shape_changes_give_identical_results() {
        let shapes = [
            (3, 20, 24),
            (3, 20, 24),
            (5, 9, 40),
            (2, 33, 7),
            (3, 20, 24),
        ];
        let prm = p(12, 2e-4);
        let (mut s2, mut s3) = (TvScratch2d::new(), TvScratch3d::new());
        for (i, &(l, h, w)) in shapes.iter().enumerate() {
            let x = noisy(l, h, w, 40 + i as u64 % 2);
            let (mut a, mut b) = (x.clone(), x.clone());
            tv_chambolle_2d(&mut a, 0.1, &prm, &mut s2);
            tv2(&mut b, 0.1, prm);
            assert_eq!(a, b, "2d shape {l}x{h}x{w}");
            let (mut a, mut b) = (x.clone(), x.clone());
            tv_chambolle_3d(&mut a, 0.1, 1.0, &prm, &mut s3);
            tv3(&mut b, 0.1, 1.0, prm);
            assert_eq!(a, b, "3d shape {l}x{h}x{w}");
        }
        // repeated calls through the Denoiser objects
        let x = noisy(3, 20, 24, 1);
        let mut d2 = TvChambolle2d::new(prm);
        let mut d3 = TvChambolle3d::new(prm, 0.7);
        let (mut first2, mut first3) = (x.clone(), x.clone());
        d2.denoise(&mut first2, 0.1);
        d3.denoise(&mut first3, 0.1);
        for _ in 0..3 {
            let (mut a, mut b) = (x.clone(), x.clone());
            d2.denoise(&mut a, 0.1);
            d3.denoise(&mut b, 0.1);
            assert_eq!(a, first2);
            assert_eq!(b, first3);
        }
    }

    /// Every compiled copy this CPU runs (each forced in turn; the
    /// scratch's portable switch for the baseline) gives the baseline's
    /// bits and iteration counts.
    #[test]
    fn every_compiled_copy_of_the_kernels_agrees_bitwise() {
        use crate::simd::{Simd, forced::Forced};
        let prm = p(40, 1e-4);
        for &(l, h, w) in &[(3, 17, 45), (2, 8, 9), (4, 31, 64)] {
            let x = noisy(l, h, w, 77);
            let run = |portable: bool| {
                let (mut s2, mut s3) = (TvScratch2d::new(), TvScratch3d::new());
                s2.set_portable_only(portable);
                s3.set_portable_only(portable);
                let (mut a, mut b) = (x.clone(), x.clone());
                tv_chambolle_2d(&mut a, 0.1, &prm, &mut s2);
                tv_chambolle_3d(&mut b, 0.1, 0.8, &prm, &mut s3);
                (a, b, s2.iterations().to_vec(), s3.iterations())
            };
            let baseline = run(true);
            for simd in Simd::available() {
                let _forced = Forced::new(simd);
                assert!(run(false) == baseline, "{l}x{h}x{w}, {simd:?}");
            }
        }
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count() {
        let x = noisy(7, 19, 23, 4);
        let prm = p(25, 1e-4);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let (mut a, mut b) = (x.clone(), x.clone());
                let i2 = tv2(&mut a, 0.1, prm);
                let i3 = tv3(&mut b, 0.1, 1.0, prm);
                (a, b, i2, i3)
            })
        };
        let one = run(1);
        for t in [2, 3, 4] {
            assert!(run(t) == one, "{t} threads");
        }
    }
}
