//! Per-band Gaussian smoothing: the proxy solver's prior step (the paper's
//! "TV_σ"). Separable, edge-replicating (no darkening at the border, which
//! would bias the residual near the mask edge), parallel over bands.

use rayon::prelude::*;

use crate::simd::{Simd, kernel};

/// Normalised 1-D Gaussian taps of radius round(3σ) (at least 1): 5 taps
/// for σ = 0.5 and 0.7, 7 for σ = 1, as the paper's kernels.
pub fn gaussian_taps(sigma: f32) -> Vec<f32> {
    let r = (3.0 * sigma).round().max(1.0) as i32;
    let mut t: Vec<f32> = (-r..=r)
        .map(|i| (-0.5 * (i as f32 / sigma).powi(2)).exp())
        .collect();
    let s: f32 = t.iter().sum();
    t.iter_mut().for_each(|v| *v /= s);
    t
}

/// Smooths each (rows × cols) band of `data` in place.
pub fn smooth_bands(data: &mut [f32], rows: usize, cols: usize, taps: &[f32]) {
    smooth_step(data, None, rows, cols, taps, false);
}

/// The proxy's prior step in one pass per band: x ← clamp(G(x + step), 0, 1)
/// (no step and no clamp when `step` is `None` and `clamp` is false).
pub fn smooth_step(
    data: &mut [f32],
    step: Option<&[f32]>,
    rows: usize,
    cols: usize,
    taps: &[f32],
    clamp: bool,
) {
    let n = rows * cols;
    let simd = Simd::detect(false);
    match step {
        Some(st) => data
            .par_chunks_mut(n)
            .zip(st.par_chunks(n))
            .for_each_init(Vec::new, |tmp, (band, add)| {
                smooth_band(simd, band, Some(add), tmp, rows, cols, taps, clamp)
            }),
        None => data.par_chunks_mut(n).for_each_init(Vec::new, |tmp, band| {
            smooth_band(simd, band, None, tmp, rows, cols, taps, clamp)
        }),
    }
}

kernel!(smooth_band, smooth_band_port, smooth_band_avx,
    (band: &mut [f32], add: Option<&[f32]>, tmp: &mut Vec<f32>, rows: usize, cols: usize,
     taps: &[f32], clamp: bool) -> () = smooth_band_body(band, add, tmp, rows, cols, taps, clamp));

/// One band: band ← clamp?(G(band + add)).
#[inline(always)]
fn smooth_band_body(
    band: &mut [f32],
    add: Option<&[f32]>,
    tmp: &mut Vec<f32>,
    rows: usize,
    cols: usize,
    taps: &[f32],
    clamp: bool,
) {
    let r = taps.len() / 2;
    let n = rows * cols;
    tmp.resize(2 * cols + n, 0.0);
    let (src_row, tmp) = tmp.split_at_mut(2 * cols);
    let src_row = &mut src_row[..cols];
    // horizontal, tap-major over contiguous slices (vectorises);
    // only the r columns at each end need the edge clamp
    for row in 0..rows {
        let x = &band[row * cols..(row + 1) * cols];
        match add {
            Some(a) => {
                for ((s, &xv), &av) in src_row
                    .iter_mut()
                    .zip(x)
                    .zip(&a[row * cols..(row + 1) * cols])
                {
                    *s = xv + av;
                }
            }
            None => src_row.copy_from_slice(x),
        }
        let dst = &mut tmp[row * cols..(row + 1) * cols];
        dst.fill(0.0);
        for (j, &w) in taps.iter().enumerate() {
            let off = j as isize - r as isize;
            let lo = ((-off).max(0) as usize).min(cols);
            let hi = (cols as isize - off.max(0)).max(lo as isize) as usize;
            let shifted = &src_row[(lo as isize + off) as usize..(hi as isize + off) as usize];
            for (d, &v) in dst[lo..hi].iter_mut().zip(shifted) {
                *d += w * v;
            }
            for c in (0..lo).chain(hi..cols) {
                dst[c] += w * src_row[(c as isize + off).clamp(0, cols as isize - 1) as usize];
            }
        }
    }
    // vertical: band = tmp * taps along rows, row-wise
    for row in 0..rows {
        let dst = &mut band[row * cols..(row + 1) * cols];
        dst.fill(0.0);
        for (j, &w) in taps.iter().enumerate() {
            let rr = (row as isize + j as isize - r as isize).clamp(0, rows as isize - 1) as usize;
            for (d, &s) in dst.iter_mut().zip(&tmp[rr * cols..(rr + 1) * cols]) {
                *d += w * s;
            }
        }
        if clamp {
            dst.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preserves_constants_and_mass_and_spreads_a_point() {
        let taps = gaussian_taps(0.7);
        assert!((taps.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        let mut c = vec![0.3f32; 2 * 9 * 11];
        smooth_bands(&mut c, 9, 11, &taps);
        assert!(c.iter().all(|v| (v - 0.3).abs() < 1e-6));
        let mut p = vec![0.0f32; 9 * 11];
        p[4 * 11 + 5] = 1.0;
        smooth_bands(&mut p, 9, 11, &taps);
        assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert!(p[4 * 11 + 5] < 0.5 && p[4 * 11 + 6] > 0.05 && p[5 * 11 + 5] > 0.05);
        assert!((p[4 * 11 + 6] - p[5 * 11 + 5]).abs() < 1e-6, "isotropic");
    }

    #[test]
    fn the_avx_copy_gives_the_same_bits_as_the_portable_one() {
        let mut rng = crate::Rng::new(4);
        let (rows, cols) = (13, 37);
        let x: Vec<f32> = (0..rows * cols).map(|_| rng.uniform() as f32).collect();
        let add: Vec<f32> = (0..rows * cols)
            .map(|_| rng.uniform() as f32 - 0.5)
            .collect();
        let taps = gaussian_taps(1.0);
        let run = |avx: bool| {
            let mut b = x.clone();
            let simd = Simd { avx };
            smooth_band(
                simd,
                &mut b,
                Some(&add),
                &mut Vec::new(),
                rows,
                cols,
                &taps,
                true,
            );
            b
        };
        assert_eq!(run(false), run(Simd::detect(false).avx));
    }
}
