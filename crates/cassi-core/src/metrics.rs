//! Image-quality metrics: PSNR, SSIM, SAM.
//!
//! Every metric compares a reference `truth` cube with an `estimate` of the
//! same (bands, rows, cols) shape; a different shape is a
//! [`CassiError::Shape`](crate::CassiError::Shape) naming both. Sums are
//! accumulated in f64 and parallel work is reduced in a fixed order, so
//! results are deterministic.
//!
//! The metrics do **not** clip their inputs: callers clip reconstructions to
//! [0, 1] first if that is what they want to score. NaN in either input
//! propagates to the result.
//!
//! Definitions (also in [`METRIC_DEFINITIONS`], for reports):
//! - **PSNR** ([`psnr`]): whole cube, peak 1, `10·log10(1 / MSE)` with the MSE
//!   over all L·H·W values; `+∞` when the MSE is 0 (identical cubes).
//! - **Band-mean PSNR** ([`psnr_band_mean`]): mean over bands of the per-band
//!   PSNR (peak 1); `+∞` if any band matches exactly.
//! - **SSIM** ([`ssim`]): Wang et al. (2004) per band, as scikit-image's
//!   `structural_similarity(data_range=1, gaussian_weights=True, sigma=1.5,
//!   use_sample_covariance=False)` computes it, averaged over bands.
//! - **SAM** ([`sam_deg`]): spectral angle in degrees per pixel, averaged over
//!   the pixels where both spectra have non-zero norm.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cube::Cube;
use crate::error::{Result, shape_error};

/// One line per metric, naming its exact definition; put it in reports.
pub const METRIC_DEFINITIONS: &str = "\
PSNR: whole cube, peak 1, 10·log10(1/MSE) with the MSE over all L·H·W values (f64); +inf when MSE = 0; inputs not clipped.
PSNR (band mean): mean over bands of the per-band PSNR (peak 1, MSE over H·W values); +inf if any band matches exactly.
SSIM: Wang et al. 2004 per band, 11×11 Gaussian window (σ = 1.5, truncate 3.5), K1 = 0.01, K2 = 0.03, data range 1, population covariances, mean of the SSIM map after cropping 5 pixels at each border (= scikit-image structural_similarity(data_range=1, gaussian_weights=True, use_sample_covariance=False)); mean over bands.
SAM: angle in degrees between truth and estimate spectra (arccos of the clamped cosine, f64) per pixel, mean over pixels where both spectra have non-zero norm (0 if there are none).";

/// Gaussian σ of the SSIM window, in pixels.
pub const SSIM_SIGMA: f64 = 1.5;
/// Half-width of the SSIM window: `int(3.5 · σ + 0.5)` as in scipy, so the
/// window is 11 × 11.
pub const SSIM_RADIUS: usize = 5;
/// Side of the SSIM window (11).
pub const SSIM_WIN: usize = 2 * SSIM_RADIUS + 1;
/// SSIM stabilising constants for data range 1: C1 = (K1·1)², C2 = (K2·1)².
pub const SSIM_K1: f64 = 0.01;
pub const SSIM_K2: f64 = 0.03;

/// The four scores of one reconstruction; see [`METRIC_DEFINITIONS`].
///
/// JSON has no infinity: serde_json writes an infinite PSNR as `null`, and
/// the PSNR fields read `null` back as `+∞`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Whole-cube PSNR in dB, peak 1 (`+∞` for a perfect estimate).
    #[serde(deserialize_with = "null_as_infinity")]
    pub psnr: f64,
    /// Mean over bands of the per-band PSNR in dB, peak 1.
    #[serde(deserialize_with = "null_as_infinity")]
    pub psnr_band_mean: f64,
    /// SSIM averaged over bands, in [−1, 1].
    pub ssim: f64,
    /// Mean spectral angle in degrees.
    pub sam_deg: f64,
}

fn null_as_infinity<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

/// All four metrics of `estimate` against `truth`.
pub fn evaluate(truth: &Cube, estimate: &Cube) -> Result<Metrics> {
    check_pair(truth, estimate)?;
    let sse = band_sse(truth, estimate);
    let ssim = ssim(truth, estimate)?;
    let sam_deg = sam_deg(truth, estimate)?;
    Ok(Metrics {
        psnr: psnr_from_sse(&sse, truth.band_len()),
        psnr_band_mean: band_mean_psnr_from_sse(&sse, truth.band_len()),
        ssim,
        sam_deg,
    })
}

/// PSNR over the whole cube with peak 1: `10·log10(1 / MSE)`, the MSE taken
/// over all L·H·W values and accumulated in f64.
///
/// Identical cubes (MSE = 0) give `f64::INFINITY`. Inputs are not clipped.
pub fn psnr(truth: &Cube, estimate: &Cube) -> Result<f64> {
    check_pair(truth, estimate)?;
    Ok(psnr_from_sse(&band_sse(truth, estimate), truth.band_len()))
}

/// PSNR of each band (peak 1, MSE over that band's H·W values);
/// `f64::INFINITY` for a band that matches exactly.
pub fn psnr_per_band(truth: &Cube, estimate: &Cube) -> Result<Vec<f64>> {
    check_pair(truth, estimate)?;
    let n = truth.band_len() as f64;
    Ok(band_sse(truth, estimate)
        .into_iter()
        .map(|s| psnr_from_mse(s / n))
        .collect())
}

/// Mean over bands of the per-band PSNR (peak 1). `f64::INFINITY` if any
/// band matches exactly.
pub fn psnr_band_mean(truth: &Cube, estimate: &Cube) -> Result<f64> {
    check_pair(truth, estimate)?;
    Ok(band_mean_psnr_from_sse(
        &band_sse(truth, estimate),
        truth.band_len(),
    ))
}

/// SSIM of each band, exactly as scikit-image's
/// `structural_similarity(a, b, data_range=1.0, gaussian_weights=True,
/// sigma=1.5, use_sample_covariance=False)` defines it:
///
/// - local means, variances and covariance from an 11 × 11 Gaussian window
///   (σ = 1.5, truncated at 3.5 σ, normalised), population (1/N) statistics;
/// - `S = (2 μx μy + C1)(2 σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2))`
///   with C1 = 0.01², C2 = 0.03² (data range 1);
/// - the mean of S over the pixels at least 5 from every border.
///
/// scikit-image filters with scipy's `reflect` boundary, but the cropped
/// pixels are exactly those whose window reaches past the border, so only
/// interior windows are ever evaluated here and the boundary rule never
/// enters. Each band must be at least 11 × 11.
pub fn ssim_per_band(truth: &Cube, estimate: &Cube) -> Result<Vec<f64>> {
    check_pair(truth, estimate)?;
    let (_, rows, cols) = truth.shape();
    if rows < SSIM_WIN || cols < SSIM_WIN {
        return Err(shape_error(
            "SSIM band image",
            format!("{rows}×{cols}"),
            format!("at least {SSIM_WIN}×{SSIM_WIN} (the Gaussian window)"),
        ));
    }
    let w = gaussian_window();
    Ok((0..truth.bands())
        .into_par_iter()
        .map(|k| ssim_band(truth.band(k), estimate.band(k), rows, cols, &w))
        .collect())
}

/// Mean over bands of [`ssim_per_band`].
pub fn ssim(truth: &Cube, estimate: &Cube) -> Result<f64> {
    let per_band = ssim_per_band(truth, estimate)?;
    Ok(per_band.iter().sum::<f64>() / per_band.len() as f64)
}

/// Mean spectral angle in degrees. Per pixel the angle between the truth and
/// estimate spectra (L-vectors) is `acos(clamp(t·e / sqrt(|t|²|e|²), −1, 1))`,
/// computed in f64.
///
/// Pixels where either spectrum has zero norm have no defined angle and are
/// **excluded** from the mean; if every pixel is excluded the result is 0.
pub fn sam_deg(truth: &Cube, estimate: &Cube) -> Result<f64> {
    check_pair(truth, estimate)?;
    let (bands, rows, cols) = truth.shape();
    let n = rows * cols;
    let (t, e) = (truth.as_slice(), estimate.as_slice());
    // Row-sized chunks: per-pixel accumulators stay in cache while the
    // band loop runs, and partial sums are reduced in chunk order.
    let chunk = cols.max(1024.min(n));
    let parts: Vec<(f64, usize)> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let p0 = c * chunk;
            let len = chunk.min(n - p0);
            let mut dot = vec![0.0f64; len];
            let mut tt = vec![0.0f64; len];
            let mut ee = vec![0.0f64; len];
            for k in 0..bands {
                let tk = &t[k * n + p0..k * n + p0 + len];
                let ek = &e[k * n + p0..k * n + p0 + len];
                for i in 0..len {
                    let (a, b) = (tk[i] as f64, ek[i] as f64);
                    dot[i] += a * b;
                    tt[i] += a * a;
                    ee[i] += b * b;
                }
            }
            let mut sum = 0.0;
            let mut count = 0;
            for i in 0..len {
                if tt[i] > 0.0 && ee[i] > 0.0 {
                    let cos = (dot[i] / (tt[i] * ee[i]).sqrt()).clamp(-1.0, 1.0);
                    sum += cos.acos();
                    count += 1;
                }
            }
            (sum, count)
        })
        .collect();
    let (sum, count) = parts
        .iter()
        .fold((0.0, 0), |(s, c), &(ps, pc)| (s + ps, c + pc));
    Ok(if count == 0 {
        0.0
    } else {
        (sum / count as f64).to_degrees()
    })
}

/// Same shape, and at least one value.
fn check_pair(truth: &Cube, estimate: &Cube) -> Result<()> {
    let fmt = |(l, h, w): (usize, usize, usize)| format!("{l}×{h}×{w}");
    if truth.shape() != estimate.shape() {
        return Err(shape_error(
            "estimate cube",
            fmt(estimate.shape()),
            format!("{} (the truth cube's shape)", fmt(truth.shape())),
        ));
    }
    if truth.as_slice().is_empty() {
        return Err(shape_error(
            "truth cube",
            fmt(truth.shape()),
            "at least one value to score",
        ));
    }
    Ok(())
}

/// Sum of squared differences of each band, f64, computed in parallel.
fn band_sse(truth: &Cube, estimate: &Cube) -> Vec<f64> {
    (0..truth.bands())
        .into_par_iter()
        .map(|k| {
            // Eight independent partial sums: vectorisable and more accurate
            // than one running sum.
            let mut acc = [0.0f64; 8];
            let (a, b) = (truth.band(k), estimate.band(k));
            let (ac, ar) = a.split_at(a.len() / 8 * 8);
            let (bc, br) = b.split_at(ac.len());
            for (x, y) in ac.chunks_exact(8).zip(bc.chunks_exact(8)) {
                for j in 0..8 {
                    let d = x[j] as f64 - y[j] as f64;
                    acc[j] += d * d;
                }
            }
            for (x, y) in ar.iter().zip(br) {
                let d = *x as f64 - *y as f64;
                acc[0] += d * d;
            }
            acc.iter().sum()
        })
        .collect()
}

fn psnr_from_mse(mse: f64) -> f64 {
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    }
}

fn psnr_from_sse(sse: &[f64], band_len: usize) -> f64 {
    psnr_from_mse(sse.iter().sum::<f64>() / (sse.len() * band_len) as f64)
}

fn band_mean_psnr_from_sse(sse: &[f64], band_len: usize) -> f64 {
    let n = band_len as f64;
    sse.iter().map(|&s| psnr_from_mse(s / n)).sum::<f64>() / sse.len() as f64
}

/// scipy's `_gaussian_kernel1d(sigma = 1.5, order 0, radius 5)`:
/// `exp(-x² / (2σ²))` for x = −5 … 5, normalised to sum 1.
fn gaussian_window() -> [f64; SSIM_WIN] {
    let mut w = [0.0; SSIM_WIN];
    let a = -0.5 / (SSIM_SIGMA * SSIM_SIGMA);
    for (i, wi) in w.iter_mut().enumerate() {
        let x = i as f64 - SSIM_RADIUS as f64;
        *wi = libm::exp(a * x * x);
    }
    let s: f64 = w.iter().sum();
    w.iter_mut().for_each(|wi| *wi /= s);
    w
}

/// Number of locally filtered quantities: x, y, x², y², x·y.
const NQ: usize = 5;

/// Mean SSIM of one band (rows, cols ≥ 11) over the valid (cropped) region.
///
/// Separable filtering over a ring of the last 11 horizontally filtered
/// rows: row r of the input is filtered along columns (valid part only,
/// cols − 10 outputs) into ring slot r mod 11; once 11 rows are in, one
/// output row is filtered along rows and its SSIM values summed.
fn ssim_band(x: &[f32], y: &[f32], rows: usize, cols: usize, w: &[f64; SSIM_WIN]) -> f64 {
    let wv = cols - 2 * SSIM_RADIUS;
    let c1 = SSIM_K1 * SSIM_K1;
    let c2 = SSIM_K2 * SSIM_K2;

    // Input row as f64 for each quantity.
    let mut q = vec![vec![0.0f64; cols]; NQ];
    // ring[slot][quantity] = horizontally filtered row.
    let mut ring = vec![vec![vec![0.0f64; wv]; NQ]; SSIM_WIN];
    // Vertically filtered output row for each quantity.
    let mut v = vec![vec![0.0f64; wv]; NQ];
    let mut total = 0.0f64;

    for r in 0..rows {
        let (xr, yr) = (&x[r * cols..(r + 1) * cols], &y[r * cols..(r + 1) * cols]);
        {
            let [qx, qy, qxx, qyy, qxy] = &mut q[..] else {
                unreachable!()
            };
            for c in 0..cols {
                let (a, b) = (xr[c] as f64, yr[c] as f64);
                qx[c] = a;
                qy[c] = b;
                qxx[c] = a * a;
                qyy[c] = b * b;
                qxy[c] = a * b;
            }
        }
        let slot = &mut ring[r % SSIM_WIN];
        for (src, dst) in q.iter().zip(slot.iter_mut()) {
            filter_row(src, dst, w);
        }
        if r + 1 < SSIM_WIN {
            continue;
        }
        // Output row i = r − 10 uses input rows i … i + 10.
        let i = r + 1 - SSIM_WIN;
        for (qi, out) in v.iter_mut().enumerate() {
            out.fill(0.0);
            for (t, &wt) in w.iter().enumerate() {
                let src = &ring[(i + t) % SSIM_WIN][qi];
                for (o, s) in out.iter_mut().zip(src) {
                    *o += wt * s;
                }
            }
        }
        let [ux, uy, uxx, uyy, uxy] = &v[..] else {
            unreachable!()
        };
        let mut row_sum = 0.0;
        for j in 0..wv {
            let (mx, my) = (ux[j], uy[j]);
            let vx = uxx[j] - mx * mx;
            let vy = uyy[j] - my * my;
            let vxy = uxy[j] - mx * my;
            let a1 = 2.0 * mx * my + c1;
            let a2 = 2.0 * vxy + c2;
            let b1 = mx * mx + my * my + c1;
            let b2 = vx + vy + c2;
            row_sum += (a1 * a2) / (b1 * b2);
        }
        total += row_sum;
    }
    total / ((rows - 2 * SSIM_RADIUS) * wv) as f64
}

/// Valid-mode correlation of `src` with the 11-tap window:
/// `dst[j] = Σ_t w[t] · src[j + t]`, `dst.len() = src.len() − 10`.
fn filter_row(src: &[f64], dst: &mut [f64], w: &[f64; SSIM_WIN]) {
    dst.fill(0.0);
    let n = dst.len();
    for (t, &wt) in w.iter().enumerate() {
        for (d, s) in dst.iter_mut().zip(&src[t..t + n]) {
            *d += wt * s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::CassiError;

    /// Deterministic smooth-plus-texture cube in [0, 1].
    fn test_cube(bands: usize, rows: usize, cols: usize, seed: u32) -> Cube {
        let mut data = Vec::with_capacity(bands * rows * cols);
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(12345);
        for k in 0..bands {
            for r in 0..rows {
                for c in 0..cols {
                    s ^= s << 13;
                    s ^= s >> 17;
                    s ^= s << 5;
                    let noise = (s as f32 / u32::MAX as f32) - 0.5;
                    let smooth = 0.5
                        + 0.3
                            * ((r as f32 * 0.3 + k as f32 * 0.5).sin())
                            * ((c as f32 * 0.2).cos());
                    data.push((smooth + 0.2 * noise).clamp(0.0, 1.0));
                }
            }
        }
        Cube::from_vec(bands, rows, cols, data).unwrap()
    }

    #[test]
    fn identical_cubes_are_perfect() {
        let a = test_cube(4, 20, 23, 1);
        let m = evaluate(&a, &a).unwrap();
        assert_eq!(m.psnr, f64::INFINITY);
        assert_eq!(m.psnr_band_mean, f64::INFINITY);
        assert!((m.ssim - 1.0).abs() < 1e-12, "{}", m.ssim);
        for s in ssim_per_band(&a, &a).unwrap() {
            assert!((s - 1.0).abs() < 1e-12, "{s}");
        }
        assert_eq!(m.sam_deg, 0.0);
    }

    #[test]
    fn known_mse_gives_known_psnr() {
        // Every value off by 0.1 → MSE = 0.01 → PSNR = 20 dB.
        let a = Cube::from_vec(2, 3, 4, vec![0.25; 24]).unwrap();
        let b = Cube::from_vec(2, 3, 4, vec![0.35; 24]).unwrap();
        let d = 0.35f32 as f64 - 0.25f32 as f64;
        let want = 10.0 * (1.0 / (d * d)).log10();
        assert!((psnr(&a, &b).unwrap() - want).abs() < 1e-12);
        assert!((want - 20.0).abs() < 1e-5);
        // Band 0 exact, band 1 off by 0.5 everywhere: whole-cube MSE = 0.125,
        // band PSNRs ∞ and 10·log10(4).
        let mut c = a.clone();
        c.band_mut(1).fill(0.75);
        assert!((psnr(&a, &c).unwrap() - 10.0 * 8f64.log10()).abs() < 1e-12);
        let per = psnr_per_band(&a, &c).unwrap();
        assert_eq!(per[0], f64::INFINITY);
        assert!((per[1] - 10.0 * 4f64.log10()).abs() < 1e-12);
        assert_eq!(psnr_band_mean(&a, &c).unwrap(), f64::INFINITY);
        // Not clipped: an estimate outside [0, 1] still counts in full.
        let e = Cube::from_vec(2, 3, 4, vec![1.25; 24]).unwrap();
        assert!(psnr(&a, &e).unwrap().abs() < 1e-12); // MSE = 1 → 0 dB
    }

    #[test]
    fn ssim_is_symmetric_and_below_one() {
        let a = test_cube(3, 17, 29, 2);
        let b = test_cube(3, 17, 29, 3);
        let ab = ssim_per_band(&a, &b).unwrap();
        let ba = ssim_per_band(&b, &a).unwrap();
        for (x, y) in ab.iter().zip(&ba) {
            assert!((x - y).abs() < 1e-14, "{x} vs {y}");
            assert!(*x < 0.99 && *x > -1.0, "{x}");
        }
        let mean = ab.iter().sum::<f64>() / 3.0;
        assert!((ssim(&a, &b).unwrap() - mean).abs() < 1e-15);
    }

    #[test]
    fn constant_image_offset_is_pure_luminance() {
        // Constant images have zero variance, so SSIM is the luminance term
        // (2ab + C1) / (a² + b² + C1) exactly.
        let (a, b) = (0.4f32, 0.55f32);
        let x = Cube::from_vec(1, 12, 15, vec![a; 180]).unwrap();
        let y = Cube::from_vec(1, 12, 15, vec![b; 180]).unwrap();
        let (a, b) = (a as f64, b as f64);
        let c1 = 1e-4;
        let want = (2.0 * a * b + c1) / (a * a + b * b + c1);
        assert!((ssim(&x, &y).unwrap() - want).abs() < 1e-12);
    }

    #[test]
    fn offset_of_textured_image_changes_only_luminance() {
        // y = x + c leaves local (co)variances unchanged, so the
        // contrast-structure term is 1 and S = (2μ(μ+c) + C1)/(μ² + (μ+c)² + C1)
        // with μ the local Gaussian mean of x.
        // x on a 2⁻¹² grid, so x + c is exact in f32.
        let x = test_cube(1, 19, 21, 7);
        let x = Cube::from_vec(
            1,
            19,
            21,
            x.as_slice()
                .iter()
                .map(|v| (v * 4096.0).round() / 4096.0)
                .collect(),
        )
        .unwrap();
        let c = 0.125f32;
        let y = Cube::from_vec(1, 19, 21, x.as_slice().iter().map(|v| v + c).collect()).unwrap();
        let w = gaussian_window();
        let (rows, cols) = (19, 21);
        let xs = x.band(0);
        let c = c as f64;
        let mut sum = 0.0;
        let mut n = 0;
        for i in SSIM_RADIUS..rows - SSIM_RADIUS {
            for j in SSIM_RADIUS..cols - SSIM_RADIUS {
                let mut mu = 0.0;
                for (s, ws) in w.iter().enumerate() {
                    for (t, wt) in w.iter().enumerate() {
                        mu +=
                            ws * wt * xs[(i + s - SSIM_RADIUS) * cols + j + t - SSIM_RADIUS] as f64;
                    }
                }
                let my = mu + c;
                sum += (2.0 * mu * my + 1e-4) / (mu * mu + my * my + 1e-4);
                n += 1;
            }
        }
        let want = sum / n as f64;
        let got = ssim(&x, &y).unwrap();
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        assert!(got < 1.0);
    }

    #[test]
    fn gaussian_window_matches_scipy() {
        let w = gaussian_window();
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert_eq!(w[0], w[10]);
        // scipy.ndimage._filters._gaussian_kernel1d(1.5, 0, 5)[5]
        assert!((w[5] - 0.266_011_724_861_794_36).abs() < 1e-15, "{}", w[5]);
    }

    #[test]
    fn sam_scale_invariant_and_known_angle() {
        let a = test_cube(6, 5, 7, 4);
        let b = Cube::from_vec(6, 5, 7, a.as_slice().iter().map(|v| v * 2.0).collect()).unwrap();
        assert_eq!(sam_deg(&a, &b).unwrap(), 0.0);
        // Orthogonal spectra → 90°, opposite → 180° (inputs not clipped).
        let x = Cube::from_vec(2, 1, 1, vec![1.0, 0.0]).unwrap();
        let y = Cube::from_vec(2, 1, 1, vec![0.0, 3.0]).unwrap();
        assert!((sam_deg(&x, &y).unwrap() - 90.0).abs() < 1e-12);
        let z = Cube::from_vec(2, 1, 1, vec![-1.0, 0.0]).unwrap();
        assert!((sam_deg(&x, &z).unwrap() - 180.0).abs() < 1e-12);
        // 45° between (1, 0) and (1, 1).
        let u = Cube::from_vec(2, 1, 1, vec![1.0, 1.0]).unwrap();
        assert!((sam_deg(&x, &u).unwrap() - 45.0).abs() < 1e-12);
    }

    #[test]
    fn sam_excludes_zero_norm_pixels() {
        // Pixels (bands = 2): p0 truth (1,0) est (1,1) → 45°; p1 truth zero;
        // p2 estimate zero; p3 both zero. Mean over p0 only.
        let t = Cube::from_vec(2, 1, 4, vec![1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]).unwrap();
        let e = Cube::from_vec(2, 1, 4, vec![1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0]).unwrap();
        assert!((sam_deg(&t, &e).unwrap() - 45.0).abs() < 1e-12);
        // Nothing left → 0.
        let z = Cube::zeros(2, 1, 4);
        assert_eq!(sam_deg(&t, &z).unwrap(), 0.0);
    }

    #[test]
    fn shape_errors_name_both_shapes() {
        let a = Cube::zeros(3, 12, 12);
        let b = Cube::zeros(3, 12, 13);
        for e in [
            psnr(&a, &b).unwrap_err(),
            psnr_band_mean(&a, &b).unwrap_err(),
            ssim(&a, &b).unwrap_err(),
            sam_deg(&a, &b).unwrap_err(),
            evaluate(&a, &b).unwrap_err(),
        ] {
            assert!(matches!(e, CassiError::Shape { .. }));
            let s = e.to_string();
            assert!(s.contains("3×12×13") && s.contains("3×12×12"), "{s}");
        }
        let small = Cube::zeros(2, 10, 30);
        let e = ssim(&small, &small).unwrap_err();
        assert!(matches!(e, CassiError::Shape { .. }));
        assert!(e.to_string().contains("11×11"), "{e}");
        let empty = Cube::zeros(0, 4, 4);
        assert!(psnr(&empty, &empty).is_err());
    }

    #[test]
    fn metrics_serialise_and_definitions_cover_all() {
        let m = Metrics {
            psnr: 30.5,
            psnr_band_mean: 31.0,
            ssim: 0.9,
            sam_deg: 4.25,
        };
        let s = serde_json::to_string(&m).unwrap();
        assert_eq!(serde_json::from_str::<Metrics>(&s).unwrap(), m);
        // A perfect estimate: +∞ PSNR goes to JSON null and comes back.
        let a = test_cube(2, 11, 11, 5);
        let p = evaluate(&a, &a).unwrap();
        let s = serde_json::to_string(&p).unwrap();
        assert!(s.contains("\"psnr\":null"), "{s}");
        assert_eq!(serde_json::from_str::<Metrics>(&s).unwrap(), p);
        let lines: Vec<&str> = METRIC_DEFINITIONS.lines().collect();
        assert_eq!(lines.len(), 4);
        for (line, name) in lines
            .iter()
            .zip(["PSNR:", "PSNR (band mean):", "SSIM:", "SAM:"])
        {
            assert!(line.starts_with(name), "{line}");
        }
    }
}
