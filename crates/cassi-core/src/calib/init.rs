//! A near-free global first guess of the mask shift: cross-correlate the
//! high-passed measurement with the high-passed measurement a white scene
//! would give through the nominal operator. The scene varies slowly compared
//! with the random mask texture, so after dividing each image by its local
//! mean only the (shifted) mask texture is left in both, and the correlation
//! peak sits at the shift. The peak also absorbs the mean extra dispersion
//! of a drifted a1, which the refinement then separates.

use super::smooth::{gaussian_taps, smooth_bands};
use crate::cube::{Cube, Frame, Mask, Measurement};
use crate::error::Result;
use crate::optics::{CassiOperator, DispersionModel};
use crate::params::Mismatch;

/// `img / G_σ(img) − 1` (0 where the local mean vanishes).
fn high_pass(img: &Frame) -> Vec<f32> {
    let (rows, cols) = img.shape();
    let mut low = img.as_slice().to_vec();
    smooth_bands(&mut low, rows, cols, &gaussian_taps(2.0));
    let floor = 1e-3 * img.max().max(f32::MIN_POSITIVE);
    img.as_slice()
        .iter()
        .zip(&low)
        .map(|(&v, &l)| if l > floor { v / l - 1.0 } else { 0.0 })
        .collect()
}

/// Estimated (dx, dy) of the mask in pixels, searched over ±`range` px.
pub fn correlation_shift(
    measurement: &Measurement,
    nominal_mask: &Mask,
    bands: usize,
    stride: f64,
    range: usize,
) -> Result<(f64, f64)> {
    let (h, w) = nominal_mask.shape();
    let op = CassiOperator::with_mismatch(
        nominal_mask,
        bands,
        &Mismatch::nominal(stride),
        DispersionModel::Rounded,
    )?;
    let white = op.forward(&Cube::from_vec(bands, h, w, vec![1.0; bands * h * w])?)?;
    let cols = white.cols().min(measurement.cols());
    let crop = |f: &Frame| -> Frame {
        let mut out = Frame::zeros(h, cols);
        for r in 0..h {
            out.row_mut(r).copy_from_slice(&f.row(r)[..cols]);
        }
        out
    };
    let a = high_pass(&crop(measurement));
    let b = high_pass(&crop(&white));
    let r = range as isize;
    let side = 2 * range + 1;
    let mut corr = vec![0.0f64; side * side];
    // c(sx, sy) = Σ a(p) b(p − s): the measurement's texture is the white one moved by s
    for sy in -r..=r {
        for sx in -r..=r {
            let mut acc = 0.0f64;
            for row in r..(h as isize - r) {
                let (ra, rb) = (row as usize * cols, (row - sy) as usize * cols);
                let (lo, hi) = (r as usize, cols - r as usize);
                let sa = &a[ra + lo..ra + hi];
                let sb = &b[(rb as isize + lo as isize - sx) as usize
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
    Ok((ix as f64 - r as f64 + fx, iy as f64 - r as f64 + fy))
}
