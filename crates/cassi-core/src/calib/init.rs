//! A near-free global first guess of the mask shift: cross-correlate the
//! high-passed measurement with the high-passed measurement a white scene
//! would give through the nominal operator. The scene varies slowly compared
//! with the random mask texture, so after dividing each image by its local
//! mean only the (shifted) mask texture is left in both, and the correlation
//! peak sits at the shift. The peak also absorbs the mean extra dispersion
//! of a drifted a1, which the refinement then separates.

use rayon::prelude::*;

use super::smooth::{gaussian_taps, smooth_frame_into};
use crate::cube::{Cube, Frame, Mask, Measurement};
use crate::error::Result;
use crate::optics::{CassiOperator, DispersionModel};
use crate::params::Mismatch;

/// `img / G_σ(img) − 1` (0 where the local mean vanishes): the code texture
/// with the slowly varying scene divided out.
pub(crate) fn high_pass(img: &Frame) -> Vec<f32> {
    let (rows, cols) = img.shape();
    let mut out = vec![0.0f32; rows * cols];
    high_pass_into(img.as_slice(), rows, cols, &mut out);
    out
}

/// [`high_pass`] of a rows × cols image into `out`, which also serves as
/// the local mean's buffer (no allocation).
pub(crate) fn high_pass_into(img: &[f32], rows: usize, cols: usize, out: &mut [f32]) {
    smooth_frame_into(img, rows, cols, &gaussian_taps(2.0), out);
    let max = img.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let floor = 1e-3 * max.max(f32::MIN_POSITIVE);
    out.par_iter_mut()
        .zip(img)
        .for_each(|(l, &v)| *l = if *l > floor { v / *l - 1.0 } else { 0.0 });
}

/// High-passed measurement and white-scene prediction on the common columns.
struct Textures {
    a: Vec<f32>,
    b: Vec<f32>,
    rows: usize,
    cols: usize,
}

/// The measurement's and the `nominal` instrument's (its stride and any
/// curvature the calibration holds) high-passed images.
fn textures(
    measurement: &Measurement,
    nominal_mask: &Mask,
    bands: usize,
    nominal: &Mismatch,
) -> Result<Textures> {
    let (h, w) = nominal_mask.shape();
    let op = CassiOperator::with_mismatch(nominal_mask, bands, nominal, DispersionModel::Rounded)?;
    let white = op.forward(&Cube::from_vec(bands, h, w, vec![1.0; bands * h * w])?)?;
    let cols = white.cols().min(measurement.cols());
    let crop = |f: &Frame| -> Frame {
        let mut out = Frame::zeros(h, cols);
        for r in 0..h {
            out.row_mut(r).copy_from_slice(&f.row(r)[..cols]);
        }
        out
    };
    Ok(Textures {
        a: high_pass(&crop(measurement)),
        b: high_pass(&crop(&white)),
        rows: h,
        cols,
    })
}

/// Correlation peak (sub-pixel) of the texture shift over rows `r0..r1`,
/// cols `c0..c1`, searching ±`range` px.
fn peak(
    t: &Textures,
    (r0, r1): (usize, usize),
    (c0, c1): (usize, usize),
    range: usize,
) -> (f64, f64) {
    let r = range as isize;
    let side = 2 * range + 1;
    let cols = t.cols;
    let (row_lo, row_hi) = (r0.max(range), r1.min(t.rows - range));
    let (lo, hi) = (c0.max(range), c1.min(cols - range));
    let mut corr = vec![0.0f64; side * side];
    // c(sx, sy) = Σ a(p) b(p − s): the measurement's texture is the white one moved by s
    for sy in -r..=r {
        for sx in -r..=r {
            let mut acc = 0.0f64;
            for row in row_lo..row_hi {
                let (ra, rb) = (row * cols, (row as isize - sy) as usize * cols);
                let sa = &t.a[ra + lo..ra + hi];
                let sb = &t.b[(rb as isize + lo as isize - sx) as usize
                    ..(rb as isize + hi as isize - sx) as usize];
                acc += sa.iter().zip(sb).map(|(&p, &q)| p * q).sum::<f32>() as f64;
            }
            corr[((sy + r) as usize) * side + (sx + r) as usize] = acc;
        }
    }
    let best = corr
        .iter()
        .enumerate()
        .max_by(|p, q| p.1.total_cmp(q.1))
        .map(|(i, _)| i)
        .unwrap_or(0);
    let (iy, ix) = (best / side, best % side);
    // parabolic sub-pixel refinement along each axis
    let sub = |m: f64, c: f64, p: f64| {
        let d = m - 2.0 * c + p;
        if d.abs() > 0.0 {
            (0.5 * (m - p) / d).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    };
    let at = |y: usize, x: usize| corr[y * side + x];
    let fx = if ix > 0 && ix + 1 < side {
        sub(at(iy, ix - 1), at(iy, ix), at(iy, ix + 1))
    } else {
        0.0
    };
    let fy = if iy > 0 && iy + 1 < side {
        sub(at(iy - 1, ix), at(iy, ix), at(iy + 1, ix))
    } else {
        0.0
    };
    (ix as f64 - r as f64 + fx, iy as f64 - r as f64 + fy)
}

/// Estimated (dx, dy) of the mask in pixels, searched over ±`range` px.
pub fn correlation_shift(
    measurement: &Measurement,
    nominal_mask: &Mask,
    bands: usize,
    nominal: &Mismatch,
    range: usize,
) -> Result<(f64, f64)> {
    let t = textures(measurement, nominal_mask, bands, nominal)?;
    Ok(peak(&t, (0, t.rows), (0, t.cols), range))
}

/// A window's centre (relative to the mask centre) and its texture shift.
struct WindowShift {
    row: f64,
    col: f64,
    sx: f64,
    sy: f64,
}

/// Estimated (dx, dy, θ°): local shifts on a 3×3 grid of windows, fitted by
/// a small-angle rigid motion s = d + θ·(−(row − c_row), col − c_col). A
/// drifted a1 adds the same column shift everywhere, so θ is unaffected.
pub fn correlation_pose(
    measurement: &Measurement,
    nominal_mask: &Mask,
    bands: usize,
    nominal: &Mismatch,
    range: usize,
) -> Result<(f64, f64, f64)> {
    let t = textures(measurement, nominal_mask, bands, nominal)?;
    let (h, w) = nominal_mask.shape();
    let (cy, cx) = ((h as f64 - 1.0) / 2.0, (w as f64 - 1.0) / 2.0);
    // windows over the mask's columns (plus the dispersion spread)
    let spread = t.cols - w;
    let mut rows_fit = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            let (r0, r1) = (i * h / 3, (i + 1) * h / 3);
            let (c0, c1) = (j * w / 3, (j + 1) * w / 3 + spread);
            let (sx, sy) = peak(&t, (r0, r1), (c0, c1), range);
            let (row, col) = (
                (r0 + r1) as f64 / 2.0 - cy,
                (c0 + c1 - spread) as f64 / 2.0 - cx,
            );
            rows_fit.push(WindowShift { row, col, sx, sy });
        }
    }
    // least squares: sx = dx − θ·row, sy = dy + θ·col (θ in radians)
    let n = rows_fit.len() as f64;
    let mean = |f: fn(&WindowShift) -> f64| rows_fit.iter().map(f).sum::<f64>() / n;
    let (mr, mc, msx, msy) = (
        mean(|v| v.row),
        mean(|v| v.col),
        mean(|v| v.sx),
        mean(|v| v.sy),
    );
    let num: f64 = rows_fit
        .iter()
        .map(|v| -(v.row - mr) * (v.sx - msx) + (v.col - mc) * (v.sy - msy))
        .sum();
    let den: f64 = rows_fit
        .iter()
        .map(|v| (v.row - mr).powi(2) + (v.col - mc).powi(2))
        .sum();
    let theta = if den > 0.0 { num / den } else { 0.0 };
    let dx = msx + theta * mr;
    let dy = msy - theta * mc;
    Ok((dx, dy, theta.to_degrees()))
}
