//! Spatio-spectral (3-D) Chambolle TV: [`TvChambolle3d`] /
//! [`tv_chambolle_3d`]. The algorithm, its skimage correspondence and the
//! step-size choice are described in the [`tv`](super::tv) module docs; this
//! file holds the 3-D kernels and their parallel driver.
//!
//! A full iteration walks the bands in order: computing `out` of band b+1
//! needs band b's old `p_band`, and band b's dual update needs `out` of band
//! b+1, so each worker takes a contiguous run of bands and the first `out`
//! band of every run (its halo) is computed beforehand from the old duals.

use rayon::prelude::*;

use super::tv::{
    LANES, Simd, Step, Stopper, TvChambolleParams, energy, kernel, lanes_sum, row_and_below,
};
use crate::Cube;
use crate::denoise::Denoiser;

/// The dual update of one voxel in numpy's operation order: new
/// (p_band, p_row, p_col) and the gradient norm.
#[inline(always)]
fn dual3(pa: f32, pb: f32, pc: f32, ga: f32, gb: f32, gc: f32, k: Step) -> (f32, f32, f32, f32) {
    let nrm = ((ga * ga + gb * gb) + gc * gc).sqrt();
    let den = nrm * k.tau_over_weight + 1.0;
    (
        (pa - k.tau * ga) / den,
        (pb - k.tau * gb) / den,
        (pc - k.tau * gc) / den,
        nrm,
    )
}

// ---------------------------------------------------------------------------
// 3-D row kernels: duals pb (band axis; K has μ·D_band), pr (rows), pc (cols).
// ---------------------------------------------------------------------------

/// `out = f + Kᵀp` for one row of band b: `pb_prev` is pb of band b−1 at this
/// row (zeros for b = 0), `pr_up` pr of the row above (zeros for row 0).
/// Returns Σd² of the row.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn out3_body(
    f: &[f32],
    pb: &[f32],
    pr: &[f32],
    pc: &[f32],
    pb_prev: &[f32],
    pr_up: &[f32],
    out: &mut [f32],
    mu: f32,
) -> f64 {
    let w = f.len();
    let (pb, pr, pc, pb_prev, pr_up, out) = (
        &pb[..w],
        &pr[..w],
        &pc[..w],
        &pb_prev[..w],
        &pr_up[..w],
        &mut out[..w],
    );
    let t = (-((mu * pb[0] + pr[0]) + pc[0]) + mu * pb_prev[0]) + pr_up[0];
    out[0] = f[0] + t;
    let mut d2 = (t * t) as f64;
    if w < 2 {
        return d2;
    }
    let mv = (w - 1) / LANES * LANES;
    let mut acc = [0f32; LANES];
    let it = f[1..1 + mv]
        .chunks_exact(LANES)
        .zip(pb[1..1 + mv].chunks_exact(LANES))
        .zip(pr[1..1 + mv].chunks_exact(LANES))
        .zip(pc[1..1 + mv].chunks_exact(LANES))
        .zip(pc[..mv].chunks_exact(LANES))
        .zip(pb_prev[1..1 + mv].chunks_exact(LANES))
        .zip(pr_up[1..1 + mv].chunks_exact(LANES))
        .zip(out[1..1 + mv].chunks_exact_mut(LANES));
    for (((((((f, pb), pr), pc), pcl), pbp), pru), o) in it {
        for l in 0..LANES {
            let t = ((-((mu * pb[l] + pr[l]) + pc[l]) + mu * pbp[l]) + pru[l]) + pcl[l];
            o[l] = f[l] + t;
            acc[l] += t * t;
        }
    }
    d2 += lanes_sum(&acc);
    for c in 1 + mv..w {
        let t = ((-((mu * pb[c] + pr[c]) + pc[c]) + mu * pb_prev[c]) + pr_up[c]) + pc[c - 1];
        out[c] = f[c] + t;
        d2 += (t * t) as f64;
    }
    d2
}

/// `fo ← fo + Kᵀp` for one row, in place (the last iteration).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn out3_inplace_body(
    fo: &mut [f32],
    pb: &[f32],
    pr: &[f32],
    pc: &[f32],
    pb_prev: &[f32],
    pr_up: &[f32],
    mu: f32,
) {
    let w = fo.len();
    let (pb, pr, pc, pb_prev, pr_up) = (&pb[..w], &pr[..w], &pc[..w], &pb_prev[..w], &pr_up[..w]);
    fo[0] += (-((mu * pb[0] + pr[0]) + pc[0]) + mu * pb_prev[0]) + pr_up[0];
    if w < 2 {
        return;
    }
    let mv = (w - 1) / LANES * LANES;
    let it = fo[1..1 + mv]
        .chunks_exact_mut(LANES)
        .zip(pb[1..1 + mv].chunks_exact(LANES))
        .zip(pr[1..1 + mv].chunks_exact(LANES))
        .zip(pc[1..1 + mv].chunks_exact(LANES))
        .zip(pc[..mv].chunks_exact(LANES))
        .zip(pb_prev[1..1 + mv].chunks_exact(LANES))
        .zip(pr_up[1..1 + mv].chunks_exact(LANES));
    for ((((((o, pb), pr), pc), pcl), pbp), pru) in it {
        for l in 0..LANES {
            o[l] += ((-((mu * pb[l] + pr[l]) + pc[l]) + mu * pbp[l]) + pru[l]) + pcl[l];
        }
    }
    for c in 1 + mv..w {
        fo[c] += ((-((mu * pb[c] + pr[c]) + pc[c]) + mu * pb_prev[c]) + pr_up[c]) + pc[c - 1];
    }
}

/// Dual update of one row of band b from known `out` rows: `o` (this row),
/// `o_dn` (row below; `o` for the last row), `o_nb` (same row of band b+1;
/// `o` for the last band). With `FIRST` the old duals are taken as 0.
/// Returns Σ|g|.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn upd3_body<const FIRST: bool>(
    o: &[f32],
    o_dn: &[f32],
    o_nb: &[f32],
    pb: &mut [f32],
    pr: &mut [f32],
    pc: &mut [f32],
    mu: f32,
    k: Step,
) -> f64 {
    let w = o.len();
    let (o_dn, o_nb, pb, pr, pc) = (
        &o_dn[..w],
        &o_nb[..w],
        &mut pb[..w],
        &mut pr[..w],
        &mut pc[..w],
    );
    let mut sn = 0f64;
    let mv = (w - 1) / LANES * LANES;
    let mut acc = [0f32; LANES];
    let it = o[..mv]
        .chunks_exact(LANES)
        .zip(o[1..1 + mv].chunks_exact(LANES))
        .zip(o_dn[..mv].chunks_exact(LANES))
        .zip(o_nb[..mv].chunks_exact(LANES))
        .zip(pb[..mv].chunks_exact_mut(LANES))
        .zip(pr[..mv].chunks_exact_mut(LANES))
        .zip(pc[..mv].chunks_exact_mut(LANES));
    for ((((((o, or), od), on), pb), pr), pc) in it {
        for l in 0..LANES {
            let gb = mu * (on[l] - o[l]);
            let (a0, a1, a2) = if FIRST {
                (0.0, 0.0, 0.0)
            } else {
                (pb[l], pr[l], pc[l])
            };
            let (a, b, c, n) = dual3(a0, a1, a2, gb, od[l] - o[l], or[l] - o[l], k);
            pb[l] = a;
            pr[l] = b;
            pc[l] = c;
            acc[l] += n;
        }
    }
    sn += lanes_sum(&acc);
    for c in mv..w {
        let gc = if c + 1 < w { o[c + 1] - o[c] } else { 0.0 };
        let gb = mu * (o_nb[c] - o[c]);
        let (a0, a1, a2) = if FIRST {
            (0.0, 0.0, 0.0)
        } else {
            (pb[c], pr[c], pc[c])
        };
        let (a, b, cc, n) = dual3(a0, a1, a2, gb, o_dn[c] - o[c], gc, k);
        pb[c] = a;
        pr[c] = b;
        pc[c] = cc;
        sn += n as f64;
    }
    sn
}

/// Fused 3-D step: `out` of (band b+1, row r) — `x` — and the dual update of
/// (band b, row r) — `y`, whose old pb is the `pb_prev` of `x`. `pr_up_x` is
/// pr of (b+1, r−1) (zeros for r = 0); `o_dn` is out of (b, r+1) (`oy` for
/// the last row). Returns (Σd² of x, Σ|g| of y).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn fused3_body(
    fx: &[f32],
    pbx: &[f32],
    prx: &[f32],
    pcx: &[f32],
    pr_up_x: &[f32],
    ox: &mut [f32],
    oy: &[f32],
    o_dn: &[f32],
    pby: &mut [f32],
    pry: &mut [f32],
    pcy: &mut [f32],
    mu: f32,
    k: Step,
) -> (f64, f64) {
    let w = fx.len();
    let (pbx, prx, pcx, pr_up_x, ox, oy, o_dn, pby, pry, pcy) = (
        &pbx[..w],
        &prx[..w],
        &pcx[..w],
        &pr_up_x[..w],
        &mut ox[..w],
        &oy[..w],
        &o_dn[..w],
        &mut pby[..w],
        &mut pry[..w],
        &mut pcy[..w],
    );
    // Columns are independent within this step; vector body on columns
    // 1..1+mv, column 0 and the tail in the scalar loop.
    let mv = w.saturating_sub(2) / LANES * LANES;
    let (mut ad, mut an) = ([0f32; LANES], [0f32; LANES]);
    if mv > 0 {
        let r = 1..1 + mv;
        let it = fx[r.clone()]
            .chunks_exact(LANES)
            .zip(pbx[r.clone()].chunks_exact(LANES))
            .zip(prx[r.clone()].chunks_exact(LANES))
            .zip(pcx[r.clone()].chunks_exact(LANES))
            .zip(pcx[..mv].chunks_exact(LANES))
            .zip(pr_up_x[r.clone()].chunks_exact(LANES))
            .zip(ox[r.clone()].chunks_exact_mut(LANES))
            .zip(oy[r.clone()].chunks_exact(LANES))
            .zip(oy[2..2 + mv].chunks_exact(LANES))
            .zip(o_dn[r.clone()].chunks_exact(LANES))
            .zip(pby[r.clone()].chunks_exact_mut(LANES))
            .zip(pry[r.clone()].chunks_exact_mut(LANES))
            .zip(pcy[r].chunks_exact_mut(LANES));
        for ((((((((((((f, pbn), prn), pcn), pcl), pru), on), oc), or), od), pbc), prc), pcc) in it
        {
            for l in 0..LANES {
                let t = ((-((mu * pbn[l] + prn[l]) + pcn[l]) + mu * pbc[l]) + pru[l]) + pcl[l];
                let o = f[l] + t;
                on[l] = o;
                ad[l] += t * t;
                let gb = mu * (o - oc[l]);
                let (a, b, c, n) =
                    dual3(pbc[l], prc[l], pcc[l], gb, od[l] - oc[l], or[l] - oc[l], k);
                pbc[l] = a;
                prc[l] = b;
                pcc[l] = c;
                an[l] += n;
            }
        }
    }
    let mut d2 = lanes_sum(&ad);
    let mut sn = lanes_sum(&an);
    for c in std::iter::once(0).chain(1 + mv..w) {
        let mut t = (-((mu * pbx[c] + prx[c]) + pcx[c]) + mu * pby[c]) + pr_up_x[c];
        if c > 0 {
            t += pcx[c - 1];
        }
        let o = fx[c] + t;
        ox[c] = o;
        d2 += (t * t) as f64;
        let gc = if c + 1 < w { oy[c + 1] - oy[c] } else { 0.0 };
        let gb = mu * (o - oy[c]);
        let (a, b, cc, n) = dual3(pby[c], pry[c], pcy[c], gb, o_dn[c] - oy[c], gc, k);
        pby[c] = a;
        pry[c] = b;
        pcy[c] = cc;
        sn += n as f64;
    }
    (d2, sn)
}

kernel!(out3, out3_port, out3_avx,
    (f: &[f32], pb: &[f32], pr: &[f32], pc: &[f32], pb_prev: &[f32], pr_up: &[f32],
     out: &mut [f32], mu: f32) -> f64
    = out3_body(f, pb, pr, pc, pb_prev, pr_up, out, mu));
kernel!(out3_inplace, out3_inplace_port, out3_inplace_avx,
    (fo: &mut [f32], pb: &[f32], pr: &[f32], pc: &[f32], pb_prev: &[f32], pr_up: &[f32],
     mu: f32) -> ()
    = out3_inplace_body(fo, pb, pr, pc, pb_prev, pr_up, mu));
kernel!(upd3_first, upd3_first_port, upd3_first_avx,
    (o: &[f32], o_dn: &[f32], o_nb: &[f32], pb: &mut [f32], pr: &mut [f32], pc: &mut [f32],
     mu: f32, k: Step) -> f64
    = upd3_body::<true>(o, o_dn, o_nb, pb, pr, pc, mu, k));
kernel!(upd3, upd3_port, upd3_avx,
    (o: &[f32], o_dn: &[f32], o_nb: &[f32], pb: &mut [f32], pr: &mut [f32], pc: &mut [f32],
     mu: f32, k: Step) -> f64
    = upd3_body::<false>(o, o_dn, o_nb, pb, pr, pc, mu, k));
kernel!(fused3, fused3_port, fused3_avx,
    (fx: &[f32], pbx: &[f32], prx: &[f32], pcx: &[f32], pr_up_x: &[f32], ox: &mut [f32],
     oy: &[f32], o_dn: &[f32], pby: &mut [f32], pry: &mut [f32], pcy: &mut [f32],
     mu: f32, k: Step) -> (f64, f64)
    = fused3_body(fx, pbx, prx, pcx, pr_up_x, ox, oy, o_dn, pby, pry, pcy, mu, k));

/// Everything a 3-D pass needs besides its buffers. Whole-cube arrays are
/// (bands, rows, cols); a "plane" is one band.
#[derive(Clone, Copy)]
struct Cube3d<'a> {
    w: usize,
    plane: usize,
    mu: f32,
    k: Step,
    zeros: &'a [f32],
    simd: Simd,
}

impl Cube3d<'_> {
    /// Iteration 0 on band b: p = update(K f) from p = 0. Returns Σ|g|.
    fn first_plane(
        &self,
        b: usize,
        f: &[f32],
        pb: &mut [f32],
        pr: &mut [f32],
        pc: &mut [f32],
    ) -> f64 {
        let (w, n) = (self.w, self.plane);
        let fb = &f[b * n..(b + 1) * n];
        let f_next = f.get((b + 1) * n..(b + 2) * n);
        let mut sn = 0f64;
        for r in 0..n / w {
            let rr = r * w..(r + 1) * w;
            let (row, below) = row_and_below(fb, r, w);
            let o_nb = f_next.map_or(row, |fnx| &fnx[rr.clone()]);
            sn += upd3_first(
                self.simd,
                row,
                below,
                o_nb,
                &mut pb[rr.clone()],
                &mut pr[rr.clone()],
                &mut pc[rr],
                self.mu,
                self.k,
            );
        }
        sn
    }

    /// `out` of band b (into `out`, one plane), reading whole-cube f and p.
    /// Returns Σd².
    fn out_plane(
        &self,
        b: usize,
        f: &[f32],
        pb: &[f32],
        pr: &[f32],
        pc: &[f32],
        out: &mut [f32],
    ) -> f64 {
        let (w, n) = (self.w, self.plane);
        let mut d2 = 0f64;
        for r in 0..n / w {
            let row = b * n + r * w..b * n + (r + 1) * w;
            let pb_prev = if b == 0 {
                self.zeros
            } else {
                &pb[row.start - n..row.end - n]
            };
            let pr_up = if r == 0 {
                self.zeros
            } else {
                &pr[row.start - w..row.end - w]
            };
            d2 += out3(
                self.simd,
                &f[row.clone()],
                &pb[row.clone()],
                &pr[row.clone()],
                &pc[row],
                pb_prev,
                pr_up,
                &mut out[r * w..(r + 1) * w],
                self.mu,
            );
        }
        d2
    }

    /// The last iteration on band b, in place: `fo ← fo + Kᵀp`.
    fn final_plane(&self, b: usize, fo: &mut [f32], pb: &[f32], pr: &[f32], pc: &[f32]) {
        let (w, n) = (self.w, self.plane);
        for (r, row_data) in fo.chunks_exact_mut(w).enumerate() {
            let row = b * n + r * w..b * n + (r + 1) * w;
            let pb_prev = if b == 0 {
                self.zeros
            } else {
                &pb[row.start - n..row.end - n]
            };
            let pr_up = if r == 0 {
                self.zeros
            } else {
                &pr[row.start - w..row.end - w]
            };
            out3_inplace(
                self.simd,
                row_data,
                &pb[row.clone()],
                &pr[row.clone()],
                &pc[row],
                pb_prev,
                pr_up,
                self.mu,
            );
        }
    }

    /// A full iteration on a run of bands (`o`, `f`, `pb`, `pr`, `pc` hold
    /// just those bands). The run's first `out` band comes precomputed in
    /// `halo_self`; `halo_next` is `out` of the band after the run (None at
    /// the cube's end). Per band, `sums[j] = (Σd², Σ|g|)`, the first band's
    /// Σd² excepted (the halo phase has it).
    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        o: &mut [f32],
        f: &[f32],
        pb: &mut [f32],
        pr: &mut [f32],
        pc: &mut [f32],
        halo_self: &[f32],
        halo_next: Option<&[f32]>,
        sums: &mut [(f64, f64)],
    ) {
        let (w, n) = (self.w, self.plane);
        let h = n / w;
        let nb = o.len() / n;
        o[..n].copy_from_slice(halo_self);
        for j in 0..nb {
            let mut sn = 0f64;
            if j + 1 < nb {
                let mut d2 = 0f64;
                let (o_lo, o_hi) = o.split_at_mut((j + 1) * n);
                let (oyp, oxp) = (&o_lo[j * n..], &mut o_hi[..n]);
                let (pb_lo, pb_hi) = pb.split_at_mut((j + 1) * n);
                let (pr_lo, pr_hi) = pr.split_at_mut((j + 1) * n);
                let (pc_lo, pc_hi) = pc.split_at_mut((j + 1) * n);
                let (pbyp, pryp, pcyp) = (
                    &mut pb_lo[j * n..],
                    &mut pr_lo[j * n..],
                    &mut pc_lo[j * n..],
                );
                let (pbxp, prxp, pcxp) = (&pb_hi[..n], &pr_hi[..n], &pc_hi[..n]);
                let fxp = &f[(j + 1) * n..(j + 2) * n];
                for r in 0..h {
                    let rr = r * w..(r + 1) * w;
                    let pr_up = if r == 0 {
                        self.zeros
                    } else {
                        &prxp[rr.start - w..rr.end - w]
                    };
                    let (oy, o_dn) = row_and_below(oyp, r, w);
                    let (a, b) = fused3(
                        self.simd,
                        &fxp[rr.clone()],
                        &pbxp[rr.clone()],
                        &prxp[rr.clone()],
                        &pcxp[rr.clone()],
                        pr_up,
                        &mut oxp[rr.clone()],
                        oy,
                        o_dn,
                        &mut pbyp[rr.clone()],
                        &mut pryp[rr.clone()],
                        &mut pcyp[rr],
                        self.mu,
                        self.k,
                    );
                    d2 += a;
                    sn += b;
                }
                sums[j + 1].0 = d2;
            } else {
                let oyp = &o[j * n..(j + 1) * n];
                let (pbyp, pryp, pcyp) = (
                    &mut pb[j * n..(j + 1) * n],
                    &mut pr[j * n..(j + 1) * n],
                    &mut pc[j * n..(j + 1) * n],
                );
                for r in 0..h {
                    let rr = r * w..(r + 1) * w;
                    let (oy, o_dn) = row_and_below(oyp, r, w);
                    let o_nb = halo_next.map_or(oy, |hn| &hn[rr.clone()]);
                    sn += upd3(
                        self.simd,
                        oy,
                        o_dn,
                        o_nb,
                        &mut pbyp[rr.clone()],
                        &mut pryp[rr.clone()],
                        &mut pcyp[rr],
                        self.mu,
                        self.k,
                    );
                }
            }
            sums[j].1 = sn;
        }
    }
}

/// Scratch of [`tv_chambolle_3d`]: `out` and the three duals (each
/// cube-sized), one halo band per worker, per-band partial sums. Reused while
/// the shape and worker count repeat.
#[derive(Debug, Default, Clone)]
pub struct TvScratch3d {
    shape: (usize, usize, usize),
    workers: usize,
    o: Vec<f32>,
    pb: Vec<f32>,
    pr: Vec<f32>,
    pc: Vec<f32>,
    halo: Vec<f32>,
    halo_d2: Vec<f64>,
    sums: Vec<(f64, f64)>,
    zeros: Vec<f32>,
    iterations: usize,
    portable_only: bool,
}

impl TvScratch3d {
    pub fn new() -> Self {
        Self::default()
    }

    /// Iterations run by the last call.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Use only the baseline (SSE2) kernels; see [`TvScratch2d::set_portable_only`](super::TvScratch2d::set_portable_only).
    pub fn set_portable_only(&mut self, on: bool) {
        self.portable_only = on;
    }

    fn prepare(&mut self, shape: (usize, usize, usize), workers: usize) {
        if self.shape != shape || self.workers != workers {
            let (l, h, w) = shape;
            let len = l * h * w;
            self.shape = shape;
            self.workers = workers;
            self.o = vec![0.0; len];
            self.pb = vec![0.0; len];
            self.pr = vec![0.0; len];
            self.pc = vec![0.0; len];
            self.halo = vec![0.0; workers * h * w];
            self.halo_d2 = vec![0.0; workers];
            self.sums = vec![(0.0, 0.0); l];
            self.zeros = vec![0.0; w];
        }
    }
}

/// Spatio-spectral isotropic TV denoising, in place: Chambolle's algorithm on
/// `TV_μ(u) = Σ sqrt(μ² (Δ_band u)² + (Δ_row u)² + (Δ_col u)²)` (forward
/// differences, zero across the last band/row/column), step
/// `τ = 1/(2 (2 + μ²))`, one global stopping rule (see the module docs).
/// μ = `spectral_weight` ≥ 0 (negative is taken as 0): 1 is skimage's 3-D
/// `denoise_tv_chambolle` (`channel_axis=None`) exactly; 0 decouples the
/// bands and gives [`tv_chambolle_2d`](super::tv_chambolle_2d)'s iterates band by band (identical
/// outputs when the stopping rule does not fire, e.g. `eps = 0`: the stop is
/// global here and per band there). `weight ≤ 0` (or NaN) leaves the cube
/// unchanged. The result does not depend on the thread count.
pub fn tv_chambolle_3d(
    cube: &mut Cube,
    weight: f32,
    spectral_weight: f32,
    params: &TvChambolleParams,
    scratch: &mut TvScratch3d,
) {
    let shape @ (bands, rows, cols) = cube.shape();
    let n = rows * cols;
    let len = bands * n;
    if len == 0 || weight.is_nan() || weight <= 0.0 || params.max_iter <= 1 {
        scratch.iterations = if len > 0 && weight > 0.0 {
            params.max_iter
        } else {
            0
        };
        return;
    }
    let mu = spectral_weight.max(0.0);
    let workers = rayon::current_num_threads().clamp(1, bands);
    scratch.prepare(shape, workers);
    let per = bands.div_ceil(workers);
    let runs = bands.div_ceil(per);
    let tau = 1.0 / (2.0 * (2.0 + mu as f64 * mu as f64));
    let simd = Simd::detect(scratch.portable_only);
    let TvScratch3d {
        o,
        pb,
        pr,
        pc,
        halo,
        halo_d2,
        sums,
        zeros,
        ..
    } = scratch;
    let pass = Cube3d {
        w: cols,
        plane: n,
        mu,
        k: Step::new(tau, weight),
        zeros,
        simd,
    };
    let fo = cube.as_mut_slice();
    let total = |sums: &[(f64, f64)]| {
        sums.iter()
            .fold((0f64, 0f64), |a, s| (a.0 + s.0, a.1 + s.1))
    };
    let mut stop = Stopper::default();

    // i = 0: out = f, p¹ from K f.
    {
        let f = &*fo;
        pb.par_chunks_mut(n)
            .zip(pr.par_chunks_mut(n))
            .zip(pc.par_chunks_mut(n))
            .zip(sums.par_iter_mut())
            .enumerate()
            .for_each(|(b, (((pb, pr), pc), s))| {
                *s = (0.0, pass.first_plane(b, f, pb, pr, pc));
            });
    }
    let (_, sn) = total(sums);
    stop.stop(0, energy(0.0, sn, weight, len), params.eps);

    let mut i = 1;
    loop {
        if i + 1 >= params.max_iter {
            let (pb, pr, pc) = (&pb[..], &pr[..], &pc[..]);
            fo.par_chunks_mut(n)
                .enumerate()
                .for_each(|(b, plane)| pass.final_plane(b, plane, pb, pr, pc));
            break;
        }
        // Halo phase: `out` of each run's first band, from the old duals.
        {
            let (f, pb, pr, pc) = (&*fo, &pb[..], &pr[..], &pc[..]);
            halo[..runs * n]
                .par_chunks_mut(n)
                .zip(halo_d2[..runs].par_iter_mut())
                .enumerate()
                .for_each(|(j, (h, d2))| *d2 = pass.out_plane(j * per, f, pb, pr, pc, h));
        }
        // Main phase: each run of bands on its own worker.
        {
            let (f, halo, halo_d2) = (&*fo, &halo[..runs * n], &halo_d2[..]);
            o.par_chunks_mut(per * n)
                .zip(f.par_chunks(per * n))
                .zip(pb.par_chunks_mut(per * n))
                .zip(pr.par_chunks_mut(per * n))
                .zip(pc.par_chunks_mut(per * n))
                .zip(sums.par_chunks_mut(per))
                .enumerate()
                .for_each(|(j, (((((o, f), pb), pr), pc), s))| {
                    let hs = &halo[j * n..(j + 1) * n];
                    let hn = (j + 1 < runs).then(|| &halo[(j + 1) * n..(j + 2) * n]);
                    pass.run(o, f, pb, pr, pc, hs, hn, s);
                    s[0].0 = halo_d2[j];
                });
        }
        let (d2, sn) = total(sums);
        if stop.stop(i, energy(d2, sn, weight, len), params.eps) {
            fo.par_chunks_mut(n)
                .zip(o.par_chunks(n))
                .for_each(|(d, s)| d.copy_from_slice(s));
            break;
        }
        i += 1;
    }
    scratch.iterations = i + 1;
}

/// Spatio-spectral Chambolle TV denoiser ([`tv_chambolle_3d`]); `strength` is
/// the weight λ. `spectral_weight` μ (default 1.0 = skimage's 3-D TV) scales
/// the band-direction difference inside the isotropic norm: larger μ smooths
/// spectra more, 0 makes it the per-band 2-D TV.
#[derive(Debug, Clone)]
pub struct TvChambolle3d {
    pub params: TvChambolleParams,
    pub spectral_weight: f32,
    scratch: TvScratch3d,
}

impl Default for TvChambolle3d {
    fn default() -> Self {
        Self::new(TvChambolleParams::default(), 1.0)
    }
}

impl TvChambolle3d {
    pub fn new(params: TvChambolleParams, spectral_weight: f32) -> Self {
        Self {
            params,
            spectral_weight,
            scratch: TvScratch3d::new(),
        }
    }

    /// Iterations run by the last call.
    pub fn iterations(&self) -> usize {
        self.scratch.iterations()
    }
}

impl Denoiser for TvChambolle3d {
    fn denoise(&mut self, cube: &mut Cube, strength: f32) {
        tv_chambolle_3d(
            cube,
            strength,
            self.spectral_weight,
            &self.params,
            &mut self.scratch,
        );
    }

    fn name(&self) -> String {
        "tv-chambolle-3d".into()
    }
}
