//! The crisp-cell model: the dispersed-mask model with the blur applied
//! where each crisp mask cell's light lies inside a detector pixel.
//!
//! The dispersed-mask model gives detector pixel p of band k the code
//! ((1 − f) m_top + f m_bottom)·s, s = the band's scene there (S_k x_k),
//! f the fraction of the pixel the lower mask row covers — exact for a
//! crisp code before any blur — and then blurs the band sum with the pixel
//! kernel K = G_σ ∗ tri sampled at whole pixels. A camera blurs each side
//! of the mask edge from where it lies: the upper strip [−½, ½ − f] of the
//! pixel and the lower strip [½ − f, ½], each through its own kernel
//! (`pixel_strip_kernel`), T_f + D_f = K. That error fits as a smaller σ
//! along the rows (`bench/results/blur_phase.json`: σ 0.6 fitted as 0.41
//! at ½ row); along the columns the dispersion's band sum spares it, so
//! the columns stay the dispersed-mask model's. Here, with T_f = K − D_f:
//!
//! ```text
//! y = B_col [ V_K Σ_k m_top·s  +  Σ_b V_b Σ_k w_b(f) (m_bottom − m_top)·s ]
//! ```
//!
//! V_K convolves down the columns with K's integer samples, V_b with
//! D at the fraction b/P (P + 1 bins, f split linearly between the two
//! nearest: the kernel is interpolated between fractions 1/8 apart, where
//! the dispersed-mask model interpolates between whole pixels); B_col is
//! K's samples along the rows. m_top and m_bottom are the two mask rows
//! either side of the pixel's mask edge, each interpolated along its row
//! at the pixel's mask column (the pose exact, per pixel, as the
//! dispersed-mask model's mask; θ ≠ 0 tilts the edge inside a pixel by
//! < 0.02 px, taken as level).
//!
//! At σ = 0 (D_f = f at the pixel itself) and wherever every mask edge
//! falls on a pixel edge (f = 0: D = 0) this is the dispersed-mask model
//! (tested). Every product is a sum of non-negative terms (T_f, D_f ≥ 0),
//! so A ≥ 0. Detector rows in parallel forward, bands in the adjoint (each
//! keeps its two latest back-projected detector rows): each output sums in
//! one order whatever the thread count.

use std::cell::RefCell;

use rayon::prelude::*;

use super::band_spread::BandSpread;
use super::blur::{GaussianBlur, pixel_strip_kernel};
use super::dispersion::{Dispersion, DispersionModel};
use super::operator::{CubeRows, validate_mask};
use super::warp::LandingMasks;
use crate::cube::Mask;
use crate::error::Result;
use crate::linop::{AatNormaliser, LinearOperator, NonNegativeOperator, row_sum_majoriser};
use crate::params::Mismatch;
use crate::simd::{Simd, kernel};

/// Fraction bins (P): the lower strip's kernel is interpolated between
/// fractions 1/P apart.
const PHASES: usize = 8;

/// Buffers per detector row: K's, then the P + 1 fraction bins'.
const SLOTS: usize = PHASES + 2;

/// The crisp-cell model's operator for one mismatch ψ (blur included).
#[derive(Debug, Clone)]
pub struct CrispCellOperator {
    /// The scene's shift per band (the dispersed-mask model's taps).
    dispersion: Dispersion,
    det_cols: usize,
    /// Each band's mask where its light lands.
    landing: LandingMasks,
    /// K's integer samples (normalised), along the rows and slot 0's.
    blur: GaussianBlur,
    /// Slot s's taps down the columns, n = −reach ..= reach: K, then D at
    /// b/P for b = 0 ..= P (normalised as K).
    slot_taps: Vec<Vec<f32>>,
    reach: usize,
}

thread_local! {
    /// The slots (rows × SLOTS × det cols) and the frame (rows × det cols).
    static SCRATCH: RefCell<[Vec<f32>; 2]> = RefCell::default();
}

impl CrispCellOperator {
    /// The instrument `nominal_mask` moved, dispersed and blurred as `psi`
    /// says, for cubes of `bands` bands. Its detector is the dispersed-mask
    /// model's (same shape).
    pub fn new(nominal_mask: &Mask, bands: usize, psi: &Mismatch) -> Result<Self> {
        let dispersion = Dispersion::new(bands, psi.dispersion(), DispersionModel::DispersedMask)?;
        Self::dispersed(nominal_mask, psi, dispersion)
    }

    /// As [`Self::new`] with the bands landing where `dispersion` (the
    /// dispersed-mask model's, e.g. [`Dispersion::shifted_along`]) puts them
    /// rather than where ψ's a1, a2 and α do; ψ gives the pose and σ.
    pub fn dispersed(nominal_mask: &Mask, psi: &Mismatch, dispersion: Dispersion) -> Result<Self> {
        psi.validate()?;
        validate_mask(nominal_mask, "nominal mask")?;
        if dispersion.model() != DispersionModel::DispersedMask {
            return Err(crate::error::CassiError::Meaningless {
                what: format!(
                    "the crisp-cell model on the {} model's taps",
                    dispersion.model().name()
                ),
                reason: "its columns are the dispersed-mask model's".into(),
            });
        }
        let bands = dispersion.bands();
        let (rows, cols) = nominal_mask.shape();
        let det_cols = cols + dispersion.extra_cols();
        crate::limits::check_elements(
            "the crisp-cell model's detector buffers",
            &[rows, SLOTS, det_cols],
            "one detector row per fraction bin",
        )?;
        let blur = GaussianBlur::new(psi.blur_sigma_px, rows, det_cols)?;
        let reach = blur.radius();
        let sigma = psi.blur_sigma_px;
        // D's taps normalised as K's are (K's raw samples' sum)
        let raw_sum: f64 = (-(reach as i64)..=reach as i64)
            .map(|n| pixel_strip_kernel(sigma, -0.5, 0.5, n as f64).max(0.0))
            .sum();
        let mut slot_taps = vec![blur.taps().to_vec()];
        for b in 0..=PHASES {
            let f = b as f64 / PHASES as f64;
            slot_taps.push(
                (-(reach as i64)..=reach as i64)
                    .map(|n| {
                        (pixel_strip_kernel(sigma, 0.5 - f, 0.5, n as f64).max(0.0) / raw_sum)
                            as f32
                    })
                    .collect(),
            );
        }
        let offsets = (0..bands).map(|k| dispersion.offset(k)).collect();
        Ok(Self {
            landing: LandingMasks::new(nominal_mask, &psi.pose(), offsets, rows, det_cols),
            dispersion,
            det_cols,
            blur,
            slot_taps,
            reach,
        })
    }

    /// This operator with each band's light spread along the rows as
    /// `spread` says, `spacing_px` apart (the rows' kernel; the columns'
    /// crisp edges are the spread's too: it moves whole bands).
    pub fn with_band_spread(self, spread: BandSpread, spacing_px: f64) -> Result<Self> {
        Ok(Self {
            blur: self.blur.with_spread(spread, spacing_px)?,
            ..self
        })
    }

    /// σ of the blur, pixels.
    pub fn blur_sigma_px(&self) -> f64 {
        self.blur.sigma()
    }

    pub fn bands(&self) -> usize {
        self.dispersion.bands()
    }

    /// (bands, rows, cols) of the cubes it takes.
    pub fn cube_shape(&self) -> (usize, usize, usize) {
        let mask = self.landing.nominal();
        (self.bands(), mask.rows(), mask.cols())
    }

    /// (rows, detector cols) of the measurements it makes.
    pub fn measurement_shape(&self) -> (usize, usize) {
        (self.landing.nominal().rows(), self.det_cols)
    }

    /// y = A x for a cube given row by row (the scene fit's coarse scene).
    pub(crate) fn apply_rows<R: CubeRows>(&self, x: &R, y: &mut [f32]) {
        self.forward_rows(
            |k, r, scratch: &mut R::Scratch, out: &mut [f32]| {
                out.copy_from_slice(x.row(k, r, scratch))
            },
            y,
        );
    }

    /// The detector columns band `k`'s light can reach: [lo, hi).
    fn band_cols(&self, k: usize) -> (usize, usize) {
        let lo = self.landing.first_col(k);
        (lo, (lo + self.landing.width()).min(self.det_cols))
    }

    /// Band `k`'s strips on detector row `r` over its columns
    /// ([`Self::band_cols`]), in `buf` (3 × the landing masks' width):
    /// (top, bottom, below).
    fn strips<'b>(
        &self,
        simd: Simd,
        k: usize,
        r: usize,
        buf: &'b mut [f32],
    ) -> (&'b [f32], &'b [f32], &'b [f32]) {
        let (lo, hi) = self.band_cols(k);
        let w = self.landing.width();
        let (top, rest) = buf.split_at_mut(w);
        let (bottom, below) = rest.split_at_mut(w);
        let n = hi - lo;
        let (top, bottom, below) = (&mut top[..n], &mut bottom[..n], &mut below[..n]);
        self.landing.strips_row(simd, k, r, top, bottom, below);
        (top, bottom, below)
    }

    /// y = A x for a cube whose row `r` of band `k` `row(k, r, scratch,
    /// out)` writes into `out`.
    fn forward_rows<S: Default + Send>(
        &self,
        row: impl Fn(usize, usize, &mut S, &mut [f32]) + Sync,
        y: &mut [f32],
    ) {
        assert_eq!(y.len(), self.range_len(), "CrispCellOperator::apply: y");
        let (bands, rows, cols) = self.cube_shape();
        let det = self.det_cols;
        let simd = Simd::detect(false);
        with_scratch([rows * SLOTS * det, rows * det], |[slots, frame]| {
            // each detector row's slots from every band
            slots
                .par_chunks_mut(SLOTS * det)
                .with_min_len(4)
                .enumerate()
                .for_each_init(
                    || {
                        let strips = vec![0.0f32; 3 * self.landing.width()];
                        (S::default(), vec![0.0f32; cols], vec![0.0f32; det], strips)
                    },
                    |(scratch, xrow, scene, strips), (r, out)| {
                        out.fill(0.0);
                        for k in 0..bands {
                            // s = S_k x_k on this row
                            let (lo, hi) = self.band_cols(k);
                            scene[lo..hi].fill(0.0);
                            let mut lit = false;
                            for tap in self.dispersion.taps(k) {
                                let src = r as i64 - tap.row as i64;
                                if src < 0 || src >= rows as i64 {
                                    continue;
                                }
                                row(k, src as usize, scratch, xrow);
                                let c0 = tap.col as usize;
                                scene[c0..c0 + cols]
                                    .iter_mut()
                                    .zip(xrow.iter())
                                    .for_each(|(o, &v)| *o += tap.weight * v);
                                lit = true;
                            }
                            if !lit {
                                continue;
                            }
                            let (top, bottom, below) = self.strips(simd, k, r, strips);
                            let scene = &scene[lo..hi];
                            for (run, b) in bin_runs(below) {
                                // slot 0, and the bins b and b + 1
                                let (head, tail) = out.split_at_mut((1 + b) * det);
                                let (kernel, tail) = (&mut head[lo..], &mut tail[lo..]);
                                let (lower, upper) = tail.split_at_mut(det);
                                let n = run.clone();
                                deposit_run(
                                    simd,
                                    (
                                        &mut kernel[n.clone()],
                                        &mut lower[n.clone()],
                                        &mut upper[n.clone()],
                                    ),
                                    (&top[n.clone()], &bottom[n.clone()], &below[n.clone()]),
                                    &scene[n],
                                    b as f32,
                                );
                            }
                        }
                    },
                );
            // down the columns, each slot with its kernel
            let slots = &*slots;
            let reach = self.reach as i64;
            frame
                .par_chunks_mut(det)
                .with_min_len(8)
                .enumerate()
                .for_each(|(r, out)| {
                    out.fill(0.0);
                    for (slot, taps) in self.slot_taps.iter().enumerate() {
                        for (t, &w) in taps.iter().enumerate() {
                            // out row r = source row + n, n = t − reach
                            let src = r as i64 - (t as i64 - reach);
                            if w == 0.0 || src < 0 || src >= rows as i64 {
                                continue;
                            }
                            let from = &slots[(src as usize * SLOTS + slot) * det..][..det];
                            axpy(simd, out, from, w);
                        }
                    }
                });
            // along the rows
            self.blur.apply_along_rows(frame, y);
        });
    }
}

/// The lower of the two fraction bins a share `below` of the pixel splits
/// between.
#[inline]
fn bin(below: f32) -> usize {
    ((below * PHASES as f32).max(0.0) as usize).min(PHASES - 1)
}

// One run of a detector row's pixels whose lower bin is `b`: each pixel's
// upper-side light top·s into K's slot, and the lower side's difference
// (bottom − top)·s split between bins b and b + 1 by the share t of
// `below` past bin b (compiled for the baseline target and for AVX: the
// same arithmetic per element).
kernel!(deposit_run, deposit_run_port, deposit_run_avx,
(slots: (&mut [f32], &mut [f32], &mut [f32]), strips: (&[f32], &[f32], &[f32]), scene: &[f32],
 b: f32) -> () = {
    let (kernel, lower, upper) = slots;
    let (top, bottom, below) = strips;
    let n = kernel.len();
    let (lower, upper, top, bottom, below, scene) =
        (&mut lower[..n], &mut upper[..n], &top[..n], &bottom[..n], &below[..n], &scene[..n]);
    for i in 0..n {
        let s = scene[i];
        let d = (bottom[i] - top[i]) * s;
        let t = (below[i] * PHASES as f32 - b).clamp(0.0, 1.0);
        kernel[i] += top[i] * s;
        lower[i] += (1.0 - t) * d;
        upper[i] += t * d;
    }
});

// The transpose of [`deposit_run`] for one run: what each pixel's scene
// value receives from K's slot and bins b, b + 1.
kernel!(back_run, back_run_port, back_run_avx,
(back: &mut [f32], slots: (&[f32], &[f32], &[f32]), strips: (&[f32], &[f32], &[f32]),
 b: f32) -> () = {
    let (kernel, lower, upper) = slots;
    let (top, bottom, below) = strips;
    let n = back.len();
    let (kernel, lower, upper, top, bottom, below) =
        (&kernel[..n], &lower[..n], &upper[..n], &top[..n], &bottom[..n], &below[..n]);
    for i in 0..n {
        let t = (below[i] * PHASES as f32 - b).clamp(0.0, 1.0);
        let d = (1.0 - t) * lower[i] + t * upper[i];
        back[i] = top[i] * kernel[i] + (bottom[i] - top[i]) * d;
    }
});

/// The runs of `below` whose pixels share their lower bin (one run per
/// band row when θ = 0: the products inside a run are slices).
fn bin_runs(below: &[f32]) -> impl Iterator<Item = (std::ops::Range<usize>, usize)> + '_ {
    let mut start = 0;
    std::iter::from_fn(move || {
        if start >= below.len() {
            return None;
        }
        let b = bin(below[start]);
        let end = below[start..]
            .iter()
            .position(|&f| bin(f) != b)
            .map_or(below.len(), |n| start + n);
        let run = start..end;
        start = end;
        Some((run, b))
    })
}

// out += w · x, compiled for the baseline target and for AVX (the same
// arithmetic per element in either copy).
kernel!(axpy, axpy_port, axpy_avx, (out: &mut [f32], x: &[f32], w: f32) -> () = {
    for (o, &v) in out.iter_mut().zip(x) {
        *o += w * v;
    }
});

/// Runs `f` with the thread's scratch, its buffers `lens` long (contents
/// unspecified).
fn with_scratch<T>(lens: [usize; 2], f: impl FnOnce(&mut [Vec<f32>; 2]) -> T) -> T {
    crate::scratch::with_taken(&SCRATCH, |bufs| {
        for (b, &n) in bufs.iter_mut().zip(&lens) {
            b.resize(n, 0.0);
        }
        f(bufs)
    })
}

/// Mask transmissions, split weights and the strips' kernels are ≥ 0.
impl NonNegativeOperator for CrispCellOperator {}

impl LinearOperator for CrispCellOperator {
    fn domain_len(&self) -> usize {
        let (l, h, w) = self.cube_shape();
        l * h * w
    }

    fn range_len(&self) -> usize {
        let (h, wd) = self.measurement_shape();
        h * wd
    }

    fn aat_normaliser(&self) -> Option<AatNormaliser> {
        Some(row_sum_majoriser(self))
    }

    fn apply(&self, x: &[f32], y: &mut [f32]) {
        assert_eq!(x.len(), self.domain_len(), "CrispCellOperator::apply: x");
        let (_, rows, cols) = self.cube_shape();
        self.forward_rows(
            |k, r, _: &mut (), out: &mut [f32]| {
                out.copy_from_slice(&x[(k * rows + r) * cols..][..cols])
            },
            y,
        );
    }

    fn adjoint(&self, y: &[f32], x: &mut [f32]) {
        assert_eq!(y.len(), self.range_len(), "CrispCellOperator::adjoint: y");
        assert_eq!(x.len(), self.domain_len(), "CrispCellOperator::adjoint: x");
        let (_, rows, cols) = self.cube_shape();
        let det = self.det_cols;
        let simd = Simd::detect(false);
        with_scratch([rows * SLOTS * det, rows * det], |[slots, frame]| {
            // along the rows: B_colᵀ = B_col (symmetric taps, zero outside)
            self.blur.apply_along_rows(y, frame);
            // down the columns: slot s of row src reads rows src + n
            let frame = &*frame;
            let reach = self.reach as i64;
            slots
                .par_chunks_mut(det)
                .with_min_len(8)
                .enumerate()
                .for_each(|(at, out)| {
                    let (src, slot) = (at / SLOTS, at % SLOTS);
                    out.fill(0.0);
                    for (t, &w) in self.slot_taps[slot].iter().enumerate() {
                        let r = src as i64 + (t as i64 - reach);
                        if w == 0.0 || r < 0 || r >= rows as i64 {
                            continue;
                        }
                        let from = &frame[r as usize * det..][..det];
                        axpy(simd, out, from, w);
                    }
                });
            // each band's scene rows gather what their taps' detector rows
            // read; a band's taps read rows i + r0 and i + r0 + 1, and the
            // next scene row the same one row down, so the two latest
            // back-projected rows are kept (by parity) and each is made once
            let slots = &*slots;
            x.par_chunks_mut(rows * cols).enumerate().for_each_init(
                || {
                    let strips = vec![0.0f32; 3 * self.landing.width()];
                    (vec![0.0f32; 2 * det], [usize::MAX; 2], strips)
                },
                |(back, held, strips), (k, band)| {
                    let (lo, hi) = self.band_cols(k);
                    let taps = self.dispersion.taps(k);
                    held.fill(usize::MAX);
                    for (i, xrow) in band.chunks_mut(cols).enumerate() {
                        xrow.fill(0.0);
                        for tap in taps {
                            let r = i as i64 + tap.row as i64;
                            if r < 0 || r >= rows as i64 {
                                continue;
                            }
                            let r = r as usize;
                            let back = &mut back[(r % 2) * det..][..det];
                            if held[r % 2] != r {
                                held[r % 2] = r;
                                let from = &slots[r * SLOTS * det..(r + 1) * SLOTS * det];
                                let (top, bottom, below) = self.strips(simd, k, r, strips);
                                let back = &mut back[lo..hi];
                                for (n, b) in bin_runs(below) {
                                    let at = |slot: usize| &from[slot * det + lo..][n.clone()];
                                    back_run(
                                        simd,
                                        &mut back[n.clone()],
                                        (at(0), at(1 + b), at(2 + b)),
                                        (&top[n.clone()], &bottom[n.clone()], &below[n.clone()]),
                                        b as f32,
                                    );
                                }
                            }
                            let c0 = tap.col as usize;
                            axpy(simd, xrow, &back[c0..c0 + cols], tap.weight);
                        }
                    }
                },
            );
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Cube;
    use crate::linop::adjoint_mismatch;
    use crate::optics::ModelOperator;
    use crate::optics::pixel_strip_kernel;
    use crate::synth::random_binary_mask;

    const BANDS: usize = 6;

    fn smooth_cube(rows: usize, cols: usize) -> Cube {
        Cube::from_vec(
            BANDS,
            rows,
            cols,
            (0..BANDS * rows * cols)
                .map(|i| {
                    let (k, r, c) = (i / (rows * cols), i / cols % rows, i % cols);
                    0.6 + 0.3 * ((r as f32 * 0.21 + k as f32).sin() * (c as f32 * 0.13).cos())
                })
                .collect(),
        )
        .unwrap()
    }

    fn relative_gap(a: &[f32], b: &[f32]) -> f64 {
        let num: f64 = a
            .iter()
            .zip(b)
            .map(|(&p, &q)| (p as f64 - q as f64).powi(2))
            .sum();
        let den: f64 = b.iter().map(|&q| q as f64 * q as f64).sum();
        (num / den).sqrt()
    }

    /// The crisp-cell operator's own product (a sharp `ModelOperator` of
    /// the model is the dispersed-mask model's taps).
    fn cells_forward(mask: &Mask, x: &Cube, m: &Mismatch) -> Vec<f32> {
        let op = CrispCellOperator::new(mask, BANDS, m).unwrap();
        let mut y = vec![0.0f32; op.range_len()];
        op.apply(x.as_slice(), &mut y);
        y
    }

    fn psi(dx: f64, dy: f64, theta: f64, a1: f64, alpha: f64, sigma: f64) -> Mismatch {
        Mismatch {
            dx,
            dy,
            theta_deg: theta,
            a1,
            alpha_deg: alpha,
            blur_sigma_px: sigma,
            a2: 0.0,
        }
    }

    /// θ = 0, an independent sum over detector pixels: each pixel's
    /// scene value s (bilinear at the band's offset) times the two mask
    /// rows either side of its mask edge, each through its strip's exact
    /// kernel down the columns; along the rows the linear split and K's
    /// integer samples (the dispersed-mask model's).
    fn strip_sum(mask: &Mask, x: &Cube, m: &Mismatch) -> Vec<f32> {
        let op = CrispCellOperator::new(mask, BANDS, m).unwrap();
        let (rows, cols) = mask.shape();
        let det = op.det_cols;
        let sigma = m.blur_sigma_px;
        let taps = op.blur.taps().to_vec();
        let reach = (taps.len() / 2) as i64;
        let at = |i: i64, j: i64| -> f64 {
            if i >= 0 && j >= 0 && i < rows as i64 && j < cols as i64 {
                mask.get(i as usize, j as usize) as f64
            } else {
                0.0
            }
        };
        let mut y = vec![0.0f64; rows * det];
        for k in 0..BANDS {
            let (oc, or) = op.dispersion.offset(k);
            let band = x.band(k);
            for r in 0..rows {
                for c in 0..det {
                    let s = bilinear(band, rows, cols, c as f64 - oc, r as f64 - or) as f64;
                    let (uc, ur) = (c as f64 - oc - m.dx, r as f64 - or - m.dy);
                    let (i0, j0) = (ur.floor(), uc.floor());
                    let (f, fc) = (ur - i0, uc - j0);
                    let (i0, j0) = (i0 as i64, j0 as i64);
                    let lerp = |i: i64| (1.0 - fc) * at(i, j0) + fc * at(i, j0 + 1);
                    let (top, bottom) = (lerp(i0), lerp(i0 + 1));
                    for q in 0..rows {
                        let d = q as f64 - r as f64;
                        let w = top * pixel_strip_kernel(sigma, -0.5, 0.5 - f, d)
                            + bottom * pixel_strip_kernel(sigma, 0.5 - f, 0.5, d);
                        if w == 0.0 {
                            continue;
                        }
                        for n in -reach..=reach {
                            let cc = c as i64 + n;
                            if cc >= 0 && cc < det as i64 {
                                y[q * det + cc as usize] +=
                                    s * w * taps[(n + reach) as usize] as f64;
                            }
                        }
                    }
                }
            }
        }
        y.into_iter().map(|v| v as f32).collect()
    }

    /// Bilinear sample, zero outside.
    fn bilinear(image: &[f32], rows: usize, cols: usize, c: f64, r: f64) -> f32 {
        let (c0, r0) = (c.floor(), r.floor());
        let (fc, fr) = ((c - c0) as f32, (r - r0) as f32);
        let at = |ri: f64, ci: f64| -> f32 {
            if ri >= 0.0 && ci >= 0.0 && ri < rows as f64 && ci < cols as f64 {
                image[ri as usize * cols + ci as usize]
            } else {
                0.0
            }
        };
        let top = (1.0 - fc) * at(r0, c0) + fc * at(r0, c0 + 1.0);
        let bottom = (1.0 - fc) * at(r0 + 1.0, c0) + fc * at(r0 + 1.0, c0 + 1.0);
        (1.0 - fr) * top + fr * bottom
    }

    #[test]
    fn the_adjoint_holds_for_any_pose_dispersion_and_blur() {
        let mask = random_binary_mask(17, 23, 0.5, 4).unwrap();
        for m in [
            psi(0.0, 0.0, 0.0, 2.0, 0.0, 0.0),
            psi(0.3, -0.45, 0.0, 2.04, 0.0, 0.5),
            psi(-1.2, 0.7, 0.6, 1.95, -0.8, 0.35),
            psi(2.1, -1.6, -0.9, 2.07, 1.0, 0.8),
        ] {
            let op = CrispCellOperator::new(&mask, BANDS, &m).unwrap();
            let e = adjoint_mismatch(&op, 3);
            assert!(e < 1e-5, "{m:?}: adjoint mismatch {e}");
        }
    }

    /// Every mask edge on a pixel edge, or no blur: the dispersed-mask
    /// model (bin 0's kernel is its blur's taps; at σ = 0 the strips'
    /// kernels are their widths).
    #[test]
    fn on_whole_pixels_or_sharp_it_is_the_dispersed_mask_model() {
        let mask = random_binary_mask(20, 24, 0.5, 5).unwrap();
        let x = smooth_cube(20, 24);
        for m in [
            psi(0.0, 0.0, 0.0, 2.0, 0.0, 0.0),
            psi(-1.0, 3.0, 0.0, 1.0, 0.0, 0.0),
            psi(2.0, -1.0, 0.0, 2.0, 0.0, 0.5),
            psi(-1.0, 2.0, 0.0, 1.0, 0.0, 0.7),
            psi(0.3, -0.45, 0.4, 2.07, 0.8, 0.0),
            psi(-1.7, 0.6, -0.9, 1.93, -1.0, 0.0),
        ] {
            let taps =
                ModelOperator::new(&mask, BANDS, &m, DispersionModel::DispersedMask).unwrap();
            let b = taps.forward(&x).unwrap();
            let gap = relative_gap(&cells_forward(&mask, &x, &m), b.as_slice());
            assert!(gap < 1e-6, "{m:?}: {gap}");
        }
    }

    /// Blurred, between whole pixels, it is the sum over each pixel's two
    /// strips up to the bins' interpolation (< 0.1 %), where the
    /// dispersed-mask model is an order of magnitude further off.
    #[test]
    fn blurred_between_pixels_it_is_the_sum_over_strips() {
        let mask = random_binary_mask(18, 20, 0.5, 6).unwrap();
        let x = smooth_cube(18, 20);
        for m in [
            psi(0.0, 0.5, 0.0, 2.0, 0.0, 0.6),
            psi(0.0, 0.45, 0.0, 2.0, 0.0, 0.6),
            psi(0.2, -0.3, 0.0, 1.96, -0.5, 0.4),
            psi(-0.6, 0.2, 0.0, 2.05, 0.9, 0.75),
        ] {
            let want = strip_sum(&mask, &x, &m);
            let gap = relative_gap(&cells_forward(&mask, &x, &m), &want);
            let taps =
                ModelOperator::new(&mask, BANDS, &m, DispersionModel::DispersedMask).unwrap();
            let old = relative_gap(taps.forward(&x).unwrap().as_slice(), &want);
            eprintln!("{m:?}: crisp cells {gap:.2e}, dispersed mask {old:.2e}");
            assert!(gap < 1e-3, "{m:?}: {gap}");
            assert!(old > 10.0 * gap, "{m:?}: dispersed mask {old} vs {gap}");
        }
    }
}
