//! Mask misalignment W(m; dx, dy, θ): bilinear resampling of the mask after a
//! rigid motion about its centre, with exact derivatives for calibration.
//!
//! Convention (docs/CONVENTIONS.md): a mask point u = (col, row) moves to
//! `R(θ)(u − c) + c + (dx, dy)`, c = ((W−1)/2, (H−1)/2),
//! `R(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]` on (col, row). So the warped mask
//! at detector-side pixel p samples the nominal mask at
//! `u(p) = R(−θ)(p − c − d) + c`. Samples outside the mask read 0, blended
//! bilinearly (zero padding), so W is continuous in (dx, dy, θ).

use rayon::prelude::*;

use crate::cube::{Frame, Mask};
use crate::params::MaskPose;
use crate::simd::{Simd, kernel};

/// The warped mask and its partial derivatives, pixel by pixel.
#[derive(Debug, Clone)]
pub struct WarpWithDerivatives {
    pub value: Mask,
    /// ∂W/∂dx (per pixel of shift).
    pub d_dx: Frame,
    /// ∂W/∂dy (per pixel of shift).
    pub d_dy: Frame,
    /// ∂W/∂θ per **degree**.
    pub d_theta_deg: Frame,
}

/// Where pixel (col, row) of the warped mask samples the nominal mask, and
/// the derivatives of that source point.
#[derive(Debug, Clone)]
struct SourceMap {
    cx: f64,
    cy: f64,
    dx: f64,
    dy: f64,
    cos: f64,
    sin: f64,
}

impl SourceMap {
    fn new(rows: usize, cols: usize, pose: &MaskPose) -> Self {
        let t = pose.theta_deg.to_radians();
        Self {
            cx: (cols as f64 - 1.0) / 2.0,
            cy: (rows as f64 - 1.0) / 2.0,
            dx: pose.dx,
            dy: pose.dy,
            cos: t.cos(),
            sin: t.sin(),
        }
    }

    /// (q_col, q_row) = p − c − d, the centred, un-shifted position.
    fn centred(&self, col: usize, row: usize) -> (f64, f64) {
        self.centred_at(col as f64, row as f64)
    }

    /// [`Self::centred`] at a continuous position.
    fn centred_at(&self, col: f64, row: f64) -> (f64, f64) {
        (col - self.cx - self.dx, row - self.cy - self.dy)
    }

    /// u = R(−θ) q + c.
    fn source(&self, q: (f64, f64)) -> (f64, f64) {
        (
            self.cos * q.0 + self.sin * q.1 + self.cx,
            -self.sin * q.0 + self.cos * q.1 + self.cy,
        )
    }
}

/// Bilinear sample of `m` at (u_col, u_row) with zero padding, and its
/// gradient with respect to (u_col, u_row).
fn bilinear(m: &Frame, uc: f64, ur: f64) -> (f64, f64, f64) {
    let (rows, cols) = (m.rows() as i64, m.cols() as i64);
    let i0 = uc.floor();
    let j0 = ur.floor();
    let (fc, fr) = (uc - i0, ur - j0);
    let (i0, j0) = (i0 as i64, j0 as i64);
    // Completely outside (with a one-pixel halo for the blend): zero.
    if i0 < -1 || j0 < -1 || i0 >= cols || j0 >= rows {
        return (0.0, 0.0, 0.0);
    }
    let at = |j: i64, i: i64| -> f64 {
        if i >= 0 && j >= 0 && i < cols && j < rows {
            m.get(j as usize, i as usize) as f64
        } else {
            0.0
        }
    };
    let (m00, m01, m10, m11) = (
        at(j0, i0),
        at(j0, i0 + 1),
        at(j0 + 1, i0),
        at(j0 + 1, i0 + 1),
    );
    let top = m00 + fc * (m01 - m00);
    let bottom = m10 + fc * (m11 - m10);
    let value = top + fr * (bottom - top);
    let g_col = (1.0 - fr) * (m01 - m00) + fr * (m11 - m10);
    let g_row = bottom - top;
    (value, g_col, g_row)
}

/// W(m; dx, dy, θ): the nominal mask moved by `pose`, same shape.
pub fn warp_mask(mask: &Mask, pose: &MaskPose) -> Mask {
    if pose.is_identity() {
        return mask.clone();
    }
    let (rows, cols) = mask.shape();
    let map = SourceMap::new(rows, cols, pose);
    let mut out = Frame::zeros(rows, cols);
    // rows in parallel: every search score warps the mask (8 % of a 660×714
    // calibration on one thread)
    out.as_mut_slice()
        .par_chunks_mut(cols)
        .with_min_len(16)
        .enumerate()
        .for_each(|(row, out_row)| {
            for (col, o) in out_row.iter_mut().enumerate() {
                let (uc, ur) = map.source(map.centred(col, row));
                *o = bilinear(mask, uc, ur).0 as f32;
            }
        });
    out
}

/// The mask each band sees where its light lands (the dispersed-mask
/// model): for band k the nominal mask moved by `pose` and then by band k's
/// offset (col, row), sampled bilinearly (zero outside) on the detector grid
/// with the mask's origin. Row by row ([`Self::row`]) or whole
/// ([`Self::materialise`]); a band's row is filled on the columns
/// `[lo_k, lo_k + width)` (`lo_k` = ⌊offset col⌋, `width` = mask cols + 1:
/// where that band's light can land) and never read elsewhere.
#[derive(Debug, Clone)]
pub(crate) struct LandingMasks {
    mask: Mask,
    map: SourceMap,
    offsets: Vec<(f64, f64)>,
    rows: usize,
    cols: usize,
}

impl LandingMasks {
    /// For a detector of `rows × cols` and band offsets `offsets`.
    pub(crate) fn new(
        mask: &Mask,
        pose: &MaskPose,
        offsets: Vec<(f64, f64)>,
        rows: usize,
        cols: usize,
    ) -> Self {
        Self {
            mask: mask.clone(),
            map: SourceMap::new(mask.rows(), mask.cols(), pose),
            offsets,
            rows,
            cols,
        }
    }

    /// The mask before the pose.
    pub(crate) fn nominal(&self) -> &Mask {
        &self.mask
    }

    /// The first detector column band `k`'s row is filled on.
    pub(crate) fn first_col(&self, k: usize) -> usize {
        (fast_floor(self.offsets[k].0).max(0) as usize).min(self.cols)
    }

    /// Columns per filled row: mask cols + 1.
    pub(crate) fn width(&self) -> usize {
        self.mask.cols() + 1
    }

    /// Every band's rows, band-major, rows × cols each (0 off the filled
    /// columns).
    pub(crate) fn materialise(&self) -> Vec<f32> {
        let simd = Simd::detect(false);
        let (rows, cols) = (self.rows, self.cols);
        let mut out = vec![0.0f32; self.offsets.len() * rows * cols];
        out.par_chunks_mut(cols.max(1))
            .with_min_len(16)
            .enumerate()
            .for_each(|(i, out_row)| {
                let (k, row) = (i / rows, i % rows);
                let lo = self.first_col(k);
                let hi = (lo + self.width()).min(cols);
                self.row(simd, k, row, &mut out_row[lo..hi]);
            });
        out
    }

    /// Band `k`'s mask on detector row `row`, columns `first_col(k) ..` into
    /// `out` (at most `width()` long: fewer where the detector ends).
    pub(crate) fn row(&self, simd: Simd, k: usize, row: usize, out: &mut [f32]) {
        let lo = self.first_col(k);
        let len = out.len();
        let out = std::cell::RefCell::new(out);
        self.for_each_run(
            k,
            row,
            len,
            |c, top, bottom, fr| out.borrow_mut()[c - lo] = (top + fr * (bottom - top)) as f32,
            |a, b, corners, fc, fr| {
                lerp_run(simd, &mut out.borrow_mut()[a - lo..b - lo], corners, fc, fr)
            },
        );
    }

    /// Band `k`'s mask on detector row `row` as the crisp-cell model reads
    /// it, columns `first_col(k) ..` (each slice at most `width()` long):
    /// the two mask rows either side of each pixel's mask edge, each
    /// interpolated along its row (`top`, `bottom`), and the share of the
    /// pixel below the edge (`below`); [`Self::row`] is
    /// top + below · (bottom − top).
    pub(crate) fn strips_row(
        &self,
        simd: Simd,
        k: usize,
        row: usize,
        top: &mut [f32],
        bottom: &mut [f32],
        below: &mut [f32],
    ) {
        let lo = self.first_col(k);
        let len = top.len();
        let outs = std::cell::RefCell::new((top, bottom, below));
        self.for_each_run(
            k,
            row,
            len,
            |c, t, b, fr| {
                let (top, bottom, below) = &mut *outs.borrow_mut();
                (top[c - lo], bottom[c - lo], below[c - lo]) = (t as f32, b as f32, fr as f32);
            },
            |a, b, corners, fc, fr| {
                let (top, bottom, below) = &mut *outs.borrow_mut();
                let r = a - lo..b - lo;
                strips_run(
                    simd,
                    (&mut top[r.clone()], &mut bottom[r.clone()], &mut below[r]),
                    corners,
                    fc,
                    fr,
                )
            },
        );
    }

    /// Band `k`'s detector row `row` over `len` columns from
    /// `first_col(k)`, column by column (`general(col, top, bottom, fr)`:
    /// the two mask rows' values at the source column and the source's
    /// row fraction) or, where the four neighbours are contiguous, a run
    /// at a time (`run(a, b, corners, (fc, dfc), (fr, dfr))`: columns
    /// a..b, the neighbours' slices, the fractions at a and their change
    /// per column).
    #[allow(clippy::type_complexity)]
    fn for_each_run(
        &self,
        k: usize,
        row: usize,
        len: usize,
        mut general: impl FnMut(usize, f64, f64, f64),
        mut run: impl FnMut(usize, usize, (&[f32], &[f32], &[f32], &[f32]), (f32, f32), (f32, f32)),
    ) {
        let map = &self.map;
        let (mr, mc) = (self.mask.rows() as i64, self.mask.cols() as i64);
        let m = self.mask.as_slice();
        let lo = self.first_col(k);
        let hi = lo + len;
        let (dc, dr) = self.offsets[k];
        // source of detector pixel (col, row) for band k: the pose's
        // source of (col − dc, row − dr)
        let qr = row as f64 - dr - map.cy - map.dy;
        let base_c = map.sin * qr + map.cx;
        let base_r = map.cos * qr + map.cy;
        let source = |col: usize| {
            let qc = col as f64 - dc - map.cx - map.dx;
            (map.cos * qc + base_c, -map.sin * qc + base_r)
        };
        // any pixel, edges and outside included
        let at = |j: i64, i: i64| -> f64 {
            if i >= 0 && j >= 0 && i < mc && j < mr {
                m[(j * mc + i) as usize] as f64
            } else {
                0.0
            }
        };
        let mut general = |col: usize| {
            let (uc, ur) = source(col);
            let (i0, j0) = (fast_floor(uc), fast_floor(ur));
            let (fc, fr) = (uc - i0 as f64, ur - j0 as f64);
            let (m00, m01) = (at(j0, i0), at(j0, i0 + 1));
            let (m10, m11) = (at(j0 + 1, i0), at(j0 + 1, i0 + 1));
            general(col, m00 + fc * (m01 - m00), m10 + fc * (m11 - m10), fr)
        };
        // Along a row the source moves by (cos θ, −sin θ) per column, so
        // ⌊u_col⌋ − col and ⌊u_row⌋ hold for long runs (θ ≤ 1°: ≥ 57
        // columns): inside a run the four neighbours are contiguous in
        // two mask rows and need no floor or edge test.
        let mut col = lo;
        while col < hi {
            let (uc, ur) = source(col);
            let (i0, j0) = (fast_floor(uc), fast_floor(ur));
            let run_len = run_length(uc - i0 as f64, map.cos - 1.0)
                .min(run_length(ur - j0 as f64, -map.sin))
                .min(hi - col);
            let end = col + run_len;
            let di = i0 - col as i64;
            let (a, b) = if j0 >= 0 && j0 + 1 < mr {
                // c + di ≥ 0 and c + di + 1 < mc
                let a = (col as i64).max(-di).min(end as i64) as usize;
                let b = (end as i64).min(mc - 1 - di).max(a as i64) as usize;
                (a, b)
            } else {
                (end, end)
            };
            for c in col..a {
                general(c);
            }
            if b > a {
                let top_row = &m[(j0 * mc) as usize..((j0 + 1) * mc) as usize];
                let bottom_row = &m[((j0 + 1) * mc) as usize..((j0 + 2) * mc) as usize];
                let first = (a as i64 + di) as usize;
                let n = b - a;
                let (t0, t1) = (
                    &top_row[first..first + n],
                    &top_row[first + 1..first + n + 1],
                );
                let (b0, b1) = (
                    &bottom_row[first..first + n],
                    &bottom_row[first + 1..first + n + 1],
                );
                // fractions at column a, and their change per column
                let (uc, ur) = source(a);
                let (fc, fr) = (uc - (a as i64 + di) as f64, ur - j0 as f64);
                run(
                    a,
                    b,
                    (t0, t1, b0, b1),
                    (fc as f32, (map.cos - 1.0) as f32),
                    (fr as f32, -map.sin as f32),
                );
            }
            for c in b..end {
                general(c);
            }
            col = end;
        }
    }
}

// One run of a landing-mask row: the four neighbours in contiguous slices,
// the fractions linear in the column (f32: the lanes vectorise).
kernel!(lerp_run, lerp_run_port, lerp_run_avx,
(out: &mut [f32], corners: (&[f32], &[f32], &[f32], &[f32]), col_fraction: (f32, f32),
 row_fraction: (f32, f32)) -> () = {
    let (t0, t1, b0, b1) = corners;
    let n = out.len();
    let (t0, t1, b0, b1) = (&t0[..n], &t1[..n], &b0[..n], &b1[..n]);
    for (t, o) in out.iter_mut().enumerate() {
        let fc = col_fraction.0 + t as f32 * col_fraction.1;
        let fr = row_fraction.0 + t as f32 * row_fraction.1;
        let top = t0[t] + fc * (t1[t] - t0[t]);
        let bottom = b0[t] + fc * (b1[t] - b0[t]);
        *o = top + fr * (bottom - top);
    }
});

// One run of a crisp-cell row: each pixel's two mask rows and the share
// below its mask edge ([`LandingMasks::strips_row`]).
kernel!(strips_run, strips_run_port, strips_run_avx,
(out: (&mut [f32], &mut [f32], &mut [f32]), corners: (&[f32], &[f32], &[f32], &[f32]),
 col_fraction: (f32, f32), row_fraction: (f32, f32)) -> () = {
    let (top, bottom, below) = out;
    let (t0, t1, b0, b1) = corners;
    let n = top.len();
    let (bottom, below) = (&mut bottom[..n], &mut below[..n]);
    let (t0, t1, b0, b1) = (&t0[..n], &t1[..n], &b0[..n], &b1[..n]);
    for t in 0..n {
        let fc = col_fraction.0 + t as f32 * col_fraction.1;
        top[t] = t0[t] + fc * (t1[t] - t0[t]);
        bottom[t] = b0[t] + fc * (b1[t] - b0[t]);
        below[t] = row_fraction.0 + t as f32 * row_fraction.1;
    }
});

/// How many columns from here (≥ 1) a fraction `g` ∈ [0, 1) stays in
/// [0, 1) while it changes by `slope` per column (with a safety margin of
/// 10⁻³ column, so rounding never carries it past the edge).
fn run_length(g: f64, slope: f64) -> usize {
    const MARGIN: f64 = 1e-3;
    let t = if slope < 0.0 {
        g / -slope
    } else if slope > 0.0 {
        (1.0 - g) / slope
    } else {
        return usize::MAX;
    };
    let t = t - MARGIN;
    if t >= usize::MAX as f64 / 2.0 {
        usize::MAX / 2
    } else if t < 0.0 {
        1
    } else {
        t as usize + 1
    }
}

/// ⌊x⌋ for |x| < 2⁶²: without SSE4.1 `f64::floor` is a library call, and
/// the band masks take two per sample.
#[inline]
fn fast_floor(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) > x { i - 1 } else { i }
}

/// W(m; ψ) with ∂W/∂dx, ∂W/∂dy and ∂W/∂θ (per degree). Exact derivatives of
/// the bilinear interpolant (one-sided where a sample point sits exactly on
/// a pixel edge, where the interpolant has a kink).
pub fn warp_mask_with_derivatives(mask: &Mask, pose: &MaskPose) -> WarpWithDerivatives {
    let (rows, cols) = mask.shape();
    let map = SourceMap::new(rows, cols, pose);
    let mut value = Frame::zeros(rows, cols);
    let mut d_dx = Frame::zeros(rows, cols);
    let mut d_dy = Frame::zeros(rows, cols);
    let mut d_theta = Frame::zeros(rows, cols);
    let (c, s) = (map.cos, map.sin);
    let per_degree = std::f64::consts::PI / 180.0;
    for row in 0..rows {
        for col in 0..cols {
            let q = map.centred(col, row);
            let (uc, ur) = map.source(q);
            let (v, gc, gr) = bilinear(mask, uc, ur);
            // ∂u/∂dx = −R(−θ)e_col = −(cos, −sin); ∂u/∂dy = −R(−θ)e_row = −(sin, cos)
            // ∂u/∂θ = dR(−θ)/dθ q = (−sin q_c + cos q_r, −cos q_c − sin q_r)
            let i = row * cols + col;
            value.as_mut_slice()[i] = v as f32;
            d_dx.as_mut_slice()[i] = (-(gc * c) + gr * s) as f32;
            d_dy.as_mut_slice()[i] = (-(gc * s) - gr * c) as f32;
            let du_c = -s * q.0 + c * q.1;
            let du_r = -c * q.0 - s * q.1;
            d_theta.as_mut_slice()[i] = ((gc * du_c + gr * du_r) * per_degree) as f32;
        }
    }
    WarpWithDerivatives {
        value,
        d_dx,
        d_dy,
        d_theta_deg: d_theta,
    }
}

/// How far a mask of `rows × cols` posed by `pose` and dispersed by
/// `offsets` (each band's (col, row) offset) lands from whole pixels:
/// 6 · mean f(1 − f) of the fractional parts f of the source coordinates
/// the detector's pixels sample (every band, every `LANDING_PHASE_STEP`-th
/// row and column of the mask's footprint), rows and columns apart, the
/// larger. 0 when every mask edge lands on a pixel edge — where the
/// bilinear sampling is exact, and the dispersed-mask model with it — and
/// ≈ 1 when the fractions spread evenly over [0, 1) (a rotated mask, a
/// non-integer stride); a half-pixel shift alone gives 1.5.
pub fn landing_phase(rows: usize, cols: usize, pose: &MaskPose, offsets: &[(f64, f64)]) -> f64 {
    let map = SourceMap::new(rows, cols, pose);
    let spread = |u: f64| {
        let f = u - u.floor();
        f * (1.0 - f)
    };
    let (mut sum_r, mut sum_c, mut n) = (0.0f64, 0.0f64, 0usize);
    for &(dc, dr) in offsets {
        for row in (0..rows).step_by(LANDING_PHASE_STEP) {
            for col in (0..cols).step_by(LANDING_PHASE_STEP) {
                // the detector pixel over mask pixel (col, row) for this band
                let (pc, pr) = ((col as f64 + dc).round(), (row as f64 + dr).round());
                let (uc, ur) = map.source(map.centred_at(pc - dc, pr - dr));
                sum_c += spread(uc);
                sum_r += spread(ur);
                n += 1;
            }
        }
    }
    if n == 0 {
        return 0.0;
    }
    6.0 * sum_r.max(sum_c) / n as f64
}

/// The sampling of [`landing_phase`], pixels.
const LANDING_PHASE_STEP: usize = 4;

/// W(m; ψ) as a physical mask does it: each detector pixel's value is the
/// mean transmission over its area of the mask's crisp squares moved by
/// `pose` (square j covers [j − ½, j + ½)), integrated by `samples` ×
/// `samples` point samples (the crisp-square lookup of the physical
/// simulator, `optics::physical`).
///
/// Why the model keeps the bilinear warp: for a translation the overlap of
/// a unit square moved by (dx, dy) with a detector pixel is exactly
/// tri(x)·tri(y), tri(t) = max(0, 1 − |t|) — bilinear interpolation. So
/// [`warp_mask`] *is* the exact pixel-area warp when θ = 0, and for small θ
/// it departs from it only where a rotated square's corners cross a pixel
/// edge (measured in the tests, 40×40 random binary mask, 64×64 samples:
/// at most 0.010 transmission for θ ≤ 1°, 0.078 at θ = 30°).
pub fn warp_mask_area(mask: &Mask, pose: &MaskPose, samples: usize) -> Mask {
    let (rows, cols) = mask.shape();
    let s = samples.max(1);
    let map = SourceMap::new(rows, cols, pose);
    let offsets: Vec<f64> = (0..s)
        .map(|a| (a as f64 - (s as f64 - 1.0) / 2.0) / s as f64)
        .collect();
    let weight = 1.0 / (s * s) as f64;
    let mut out = Frame::zeros(rows, cols);
    for row in 0..rows {
        let out_row = out.row_mut(row);
        for (col, o) in out_row.iter_mut().enumerate() {
            let (qc, qr) = map.centred(col, row);
            let mut acc = 0.0f64;
            for &oy in &offsets {
                for &ox in &offsets {
                    let (uc, ur) = map.source((qc + ox, qr + oy));
                    let (j, i) = ((uc + 0.5).floor(), (ur + 0.5).floor());
                    if j >= 0.0 && i >= 0.0 && j < cols as f64 && i < rows as f64 {
                        acc += mask.get(i as usize, j as usize) as f64;
                    }
                }
            }
            *o = (acc * weight) as f32;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each band's landing mask is the warp of the mask moved by the pose
    /// and that band's offset, on every column its light can reach — run by
    /// run or pixel by pixel, poses from none to steep (short runs) and
    /// offsets that leave the mask.
    #[test]
    fn landing_masks_are_the_mask_warped_to_each_band() {
        let (rows, cols) = (23, 31);
        let mask = crate::synth::uniform_grey_mask(rows, cols, 11);
        for (dx, dy, theta) in [
            (0.0, 0.0, 0.0),
            (0.3, -1.7, 0.4),
            (-2.2, 0.6, -0.9),
            (0.5, 0.5, 25.0),
        ] {
            let pose = MaskPose {
                dx,
                dy,
                theta_deg: theta,
            };
            let offsets = [(0.0, 0.0), (2.37, 0.04), (4.74, -0.08), (7.5, 1.5)];
            let det = cols + 9;
            let landing =
                LandingMasks::new(&mask, &pose, offsets.to_vec(), rows, det).materialise();
            for (k, &(oc, or)) in offsets.iter().enumerate() {
                let moved = MaskPose {
                    dx: dx + oc,
                    dy: dy + or,
                    theta_deg: theta,
                };
                let lo = oc.floor() as usize;
                for row in 0..rows {
                    for col in lo..(lo + cols + 1).min(det) {
                        let q = (
                            col as f64 - (cols as f64 - 1.0) / 2.0 - moved.dx,
                            row as f64 - (rows as f64 - 1.0) / 2.0 - moved.dy,
                        );
                        let t = theta.to_radians();
                        let u = (
                            t.cos() * q.0 + t.sin() * q.1 + (cols as f64 - 1.0) / 2.0,
                            -t.sin() * q.0 + t.cos() * q.1 + (rows as f64 - 1.0) / 2.0,
                        );
                        let want = bilinear(&mask, u.0, u.1).0;
                        let got = landing[(k * rows + row) * det + col] as f64;
                        assert!(
                            (got - want).abs() < 1e-5,
                            "pose {pose:?} band {k} ({row}, {col}): {got} vs {want}"
                        );
                    }
                }
            }
        }
    }

    fn one_pixel(rows: usize, cols: usize, r: usize, c: usize) -> Mask {
        let mut m = Frame::zeros(rows, cols);
        m.set(r, c, 1.0);
        m
    }

    fn argmax(f: &Frame) -> (usize, usize) {
        let i = f
            .as_slice()
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(i, _)| i)
            .unwrap();
        (i / f.cols(), i % f.cols())
    }

    #[test]
    fn plus_dx_moves_right_plus_dy_moves_down() {
        let m = one_pixel(9, 11, 4, 5);
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: 2.0,
                dy: 0.0,
                theta_deg: 0.0,
            },
        );
        assert_eq!(w.get(4, 7), 1.0);
        assert_eq!(w.as_slice().iter().sum::<f32>(), 1.0);
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: 0.0,
                dy: 3.0,
                theta_deg: 0.0,
            },
        );
        assert_eq!(w.get(7, 5), 1.0);
        // a half-pixel shift splits the pixel between its two right-hand positions
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: 0.5,
                dy: 0.0,
                theta_deg: 0.0,
            },
        );
        assert!((w.get(4, 5) - 0.5).abs() < 1e-6 && (w.get(4, 6) - 0.5).abs() < 1e-6);
    }

    /// A band of rows warped with the pose as seen from it is the frame's
    /// warp there (away from the band's edges, where the frame's warp
    /// reads mask rows the band does not have); the frame's own pose is not.
    #[test]
    fn a_band_of_rows_sees_the_pose_about_its_own_centre() {
        use crate::params::Mismatch;
        let mask = crate::synth::random_binary_mask(96, 80, 0.5, 3).unwrap();
        let psi = Mismatch {
            dx: 0.3,
            dy: -0.4,
            theta_deg: 0.6,
            ..Mismatch::nominal(2.0)
        };
        let frame = warp_mask(&mask, &psi.pose());
        let (first, end) = (50, 90);
        let band = mask.rows_range(first, end).unwrap();
        let below = (first + end) as f64 / 2.0 - 96.0 / 2.0;
        let largest_difference = |pose: &MaskPose| {
            let warped = warp_mask(&band, pose);
            (6..end - first - 6)
                .flat_map(|r| (2..78).map(move |c| (r, c)))
                .map(|(r, c)| (warped.get(r, c) - frame.get(first + r, c)).abs())
                .fold(0.0f32, f32::max)
        };
        let seen = largest_difference(&psi.seen_from_rows_below(below).pose());
        assert!(seen < 1e-4, "{seen}");
        let unmoved = largest_difference(&psi.pose());
        assert!(unmoved > 0.1, "{unmoved}");
    }

    #[test]
    fn positive_theta_turns_col_axis_toward_rows_about_the_centre() {
        // 21×21 mask, centre (10, 10). A point 8 columns right of centre,
        // rotated by +90° with R(θ) on (col, row), goes to 8 rows below centre.
        let m = one_pixel(21, 21, 10, 18);
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: 0.0,
                dy: 0.0,
                theta_deg: 90.0 - 1e-9,
            },
        );
        assert_eq!(argmax(&w), (18, 10));
        // Small angle: the corner moves by ≈ r·θ, the centre pixel stays put.
        let m = one_pixel(21, 21, 10, 10);
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: 0.0,
                dy: 0.0,
                theta_deg: 5.0,
            },
        );
        assert!((w.get(10, 10) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn centre_is_the_half_pixel_midpoint_for_even_sizes() {
        // Even size 4×4: centre (1.5, 1.5). Rotating by 180° maps pixel
        // (row 0, col 0) to (row 3, col 3) exactly.
        let m = one_pixel(4, 4, 0, 0);
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: 0.0,
                dy: 0.0,
                theta_deg: 180.0 - 1e-9,
            },
        );
        assert!((w.get(3, 3) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn outside_reads_zero() {
        let m = Frame::from_vec(3, 3, vec![1.0; 9]).unwrap();
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: 1.0,
                dy: 0.0,
                theta_deg: 0.0,
            },
        );
        assert_eq!(w.row(0), &[0.0, 1.0, 1.0]);
        let w = warp_mask(
            &m,
            &MaskPose {
                dx: -10.0,
                dy: 0.0,
                theta_deg: 0.0,
            },
        );
        assert!(w.as_slice().iter().all(|&v| v == 0.0));
    }

    #[test]
    fn derivatives_match_central_differences() {
        let (rows, cols) = (24, 30);
        let m = crate::synth::uniform_grey_mask(rows, cols, 11);
        let pose = MaskPose {
            dx: 0.37,
            dy: -1.21,
            theta_deg: 0.83,
        };
        let d = warp_mask_with_derivatives(&m, &pose);
        assert_eq!(d.value, warp_mask(&m, &pose));
        let h = 1e-4;
        let fd = |p: MaskPose, q: MaskPose| -> Vec<f64> {
            let a = warp_mask_with_derivatives(&m, &p).value;
            let b = warp_mask_with_derivatives(&m, &q).value;
            a.as_slice()
                .iter()
                .zip(b.as_slice())
                .map(|(x, y)| (*x as f64 - *y as f64) / (2.0 * h))
                .collect()
        };
        let checks = [
            (
                &d.d_dx,
                fd(
                    MaskPose {
                        dx: pose.dx + h,
                        ..pose
                    },
                    MaskPose {
                        dx: pose.dx - h,
                        ..pose
                    },
                ),
            ),
            (
                &d.d_dy,
                fd(
                    MaskPose {
                        dy: pose.dy + h,
                        ..pose
                    },
                    MaskPose {
                        dy: pose.dy - h,
                        ..pose
                    },
                ),
            ),
            (
                &d.d_theta_deg,
                fd(
                    MaskPose {
                        theta_deg: pose.theta_deg + h,
                        ..pose
                    },
                    MaskPose {
                        theta_deg: pose.theta_deg - h,
                        ..pose
                    },
                ),
            ),
        ];
        for (analytic, numeric) in checks {
            let (mut err, mut scale) = (0.0f64, 0.0f64);
            for (a, n) in analytic.as_slice().iter().zip(&numeric) {
                err = err.max((*a as f64 - n).abs());
                scale = scale.max(n.abs());
            }
            // f32 values differenced at h = 1e-4 carry ~1e-3 noise
            assert!(
                scale > 0.1 && err < 5e-3 * scale.max(1.0),
                "err {err}, scale {scale}"
            );
        }
    }

    fn max_abs_diff(a: &Mask, b: &Mask) -> f32 {
        a.as_slice()
            .iter()
            .zip(b.as_slice())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max)
    }

    /// The landing phase: 0 with every edge on a pixel edge (whole-pixel
    /// shifts, an integer stride); 1.5 for half a pixel along rows or
    /// columns (f(1 − f) = ¼ everywhere); ≈ 1 for a rotated mask, a
    /// non-integer stride or a tilted dispersion, whose fractions spread.
    #[test]
    fn the_landing_phase_is_nil_on_the_grid_and_about_one_off_it() {
        let (rows, cols, bands) = (64, 64, 10);
        let stride = |a1: f64, alpha_deg: f64| -> Vec<(f64, f64)> {
            let a = alpha_deg.to_radians();
            (0..bands)
                .map(|k| (a1 * k as f64 * a.cos(), a1 * k as f64 * a.sin()))
                .collect()
        };
        let pose = |dx, dy, theta_deg| MaskPose { dx, dy, theta_deg };
        let phase = |p: MaskPose, o: Vec<(f64, f64)>| landing_phase(rows, cols, &p, &o);
        assert!(phase(pose(0.0, 0.0, 0.0), stride(2.0, 0.0)).abs() < 1e-9);
        assert!(phase(pose(-3.0, 2.0, 0.0), stride(2.0, 0.0)).abs() < 1e-9);
        assert!((phase(pose(0.0, 0.5, 0.0), stride(2.0, 0.0)) - 1.5).abs() < 1e-9);
        assert!((phase(pose(0.5, 0.0, 0.0), stride(2.0, 0.0)) - 1.5).abs() < 1e-9);
        for (p, o) in [
            (pose(0.0, 0.0, 0.6), stride(2.0, 0.0)),
            (pose(0.0, 0.0, 0.0), stride(2.1, 0.0)),
            (pose(0.0, 0.0, 0.0), stride(2.0, 0.9)),
        ] {
            let v = phase(p, o);
            assert!((0.6..1.3).contains(&v), "{p:?}: {v}");
        }
    }

    #[test]
    fn the_bilinear_warp_is_the_exact_pixel_area_warp_for_translations() {
        let mask = crate::synth::random_binary_mask(24, 20, 0.5, 9).unwrap();
        for (dx, dy) in [(0.3, -0.7), (1.5, 1.0), (-2.25, 0.6), (0.0, 0.5)] {
            let pose = MaskPose {
                dx,
                dy,
                theta_deg: 0.0,
            };
            let bilinear = warp_mask(&mask, &pose);
            // the point-sampled area converges to bilinear at rate 1/S
            let e16 = max_abs_diff(&bilinear, &warp_mask_area(&mask, &pose, 16));
            let e64 = max_abs_diff(&bilinear, &warp_mask_area(&mask, &pose, 64));
            assert!(e16 <= 2.0 / 16.0 + 1e-6, "({dx}, {dy}): {e16}");
            assert!(e64 <= 2.0 / 64.0 + 1e-6, "({dx}, {dy}): {e64}");
        }
    }

    #[test]
    fn under_a_degree_of_rotation_the_bilinear_warp_stays_within_a_percent() {
        let mask = crate::synth::random_binary_mask(40, 40, 0.5, 4).unwrap();
        for theta in [0.3, 0.8, 1.0] {
            let pose = MaskPose {
                dx: 0.4,
                dy: -0.3,
                theta_deg: theta,
            };
            let e = max_abs_diff(&warp_mask(&mask, &pose), &warp_mask_area(&mask, &pose, 64));
            eprintln!("θ {theta}°: max |bilinear − area| = {e:.4}");
            // measured ≤ 0.0096 (θ 0.3–1°)
            assert!(e < 0.015, "θ {theta}: {e}");
        }
        // a large rotation is where the two models part
        let pose = MaskPose {
            dx: 0.0,
            dy: 0.0,
            theta_deg: 30.0,
        };
        let e = max_abs_diff(&warp_mask(&mask, &pose), &warp_mask_area(&mask, &pose, 64));
        eprintln!("30°: max |bilinear − area| = {e:.4}");
        assert!(e > 0.05, "30°: {e}");
    }
}
