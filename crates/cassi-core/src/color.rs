//! Wavelength → colour: pseudo-RGB rendering of a cube.
//!
//! Each pixel's spectrum is integrated against the CIE 1931 2° colour-matching
//! functions x̄, ȳ, z̄ over the band wavelengths, XYZ is converted to linear
//! sRGB (D65), white-balanced so that a spectrally flat pixel is neutral grey,
//! normalised in brightness, and encoded with the sRGB transfer curve.
//!
//! The colour-matching functions are the multi-lobe analytic fit of Wyman,
//! Sloan & Shirley, "Simple Analytic Approximations to the CIE XYZ Color
//! Matching Functions", JCGT 2(2), 2013 (their equation 4), accurate to about
//! 1 % of the tabulated CIE 1931 2° data: no table needed.

use crate::cube::Cube;
use crate::error::{CassiError, Result};

/// An 8-bit sRGB image, rows × cols, interleaved RGB, row-major:
/// pixel (r, c) is `data[3 (r·cols + c) .. 3 (r·cols + c) + 3]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    pub rows: usize,
    pub cols: usize,
    pub data: Vec<u8>,
}

impl RgbImage {
    /// The (R, G, B) of pixel (row, col).
    pub fn pixel(&self, row: usize, col: usize) -> [u8; 3] {
        let i = 3 * (row * self.cols + col);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// The fraction of pixels allowed to saturate: the brightness is scaled so
/// that this quantile (99th percentile) of the per-pixel max(R, G, B) maps to 1.
pub const WHITE_PERCENTILE: f64 = 0.99;

/// Piecewise Gaussian of Wyman et al.: width `s1` left of `mu`, `s2` right.
fn lobe(l: f64, mu: f64, s1: f64, s2: f64) -> f64 {
    let t = (l - mu) / if l < mu { s1 } else { s2 };
    libm::exp(-0.5 * t * t)
}

/// CIE 1931 2° colour-matching functions (x̄, ȳ, z̄) at wavelength `l` nm,
/// multi-lobe fit of Wyman, Sloan & Shirley (2013).
pub fn cie1931_xyz(l: f64) -> [f64; 3] {
    let x = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7)
        - 0.065 * lobe(l, 501.1, 20.4, 26.2);
    let y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
    let z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
    [x, y, z]
}

/// XYZ → linear sRGB (IEC 61966-2-1, D65 white).
const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.2404542, -1.5371385, -0.4985314],
    [-0.9692660, 1.8760108, 0.0415560],
    [0.0556434, -0.2040259, 1.0572252],
];

/// Per-band weights `w[c][k]` so that linear, white-balanced channel c of a
/// pixel with spectrum s is Σ_k w[c][k] s_k.
///
/// Band k stands for the interval halfway to its neighbours (width
/// (λ_{k+1} − λ_{k−1}) / 2, one-sided at the ends, or 1 for a single band). Each
/// channel's weights sum to 1, so a flat spectrum of value v gives
/// (v, v, v). Errors if the wavelengths are not finite and strictly increasing,
/// or if the bands see no light of some primary (white balance impossible).
pub fn rgb_weights(wavelengths_nm: &[f64]) -> Result<[Vec<f64>; 3]> {
    let n = wavelengths_nm.len();
    if n == 0
        || wavelengths_nm.iter().any(|w| !w.is_finite())
        || wavelengths_nm.windows(2).any(|w| w[1] <= w[0])
    {
        return Err(CassiError::InvalidParameter {
            name: "wavelengths_nm",
            value: f64::NAN,
            reason: "need at least one wavelength, finite and strictly increasing".into(),
        });
    }
    let width = |k: usize| -> f64 {
        let lo = if k == 0 {
            None
        } else {
            Some(wavelengths_nm[k - 1])
        };
        let hi = wavelengths_nm.get(k + 1).copied();
        let c = wavelengths_nm[k];
        match (lo, hi) {
            (Some(a), Some(b)) => 0.5 * (b - a),
            (None, Some(b)) => b - c,
            (Some(a), None) => c - a,
            (None, None) => 1.0,
        }
    };
    let mut w: [Vec<f64>; 3] = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    for (k, &l) in wavelengths_nm.iter().enumerate() {
        let xyz = cie1931_xyz(l);
        let dl = width(k);
        for (c, row) in XYZ_TO_SRGB.iter().enumerate() {
            w[c][k] = dl * (row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2]);
        }
    }
    for (c, wc) in w.iter_mut().enumerate() {
        let total: f64 = wc.iter().sum();
        if total.is_nan() || total <= 0.0 {
            return Err(CassiError::InvalidParameter {
                name: "wavelengths_nm",
                value: total,
                reason: format!(
                    "a flat spectrum over these bands has no {} component; cannot white-balance",
                    ["red", "green", "blue"][c]
                ),
            });
        }
        wc.iter_mut().for_each(|v| *v /= total);
    }
    Ok(w)
}

/// sRGB transfer curve (linear 0…1 → encoded 0…1).
fn srgb_encode(x: f64) -> f64 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * libm::pow(x, 1.0 / 2.4) - 0.055
    }
}

/// Pseudo-RGB rendering of `cube` whose band k has centre `wavelengths_nm[k]`.
///
/// Steps: per pixel, linear RGB = Σ_k w[·][k] s_k with the weights of
/// [`rgb_weights`] (CIE 1931 integration, XYZ → linear sRGB D65, white balance
/// so that a flat spectrum is neutral grey); negatives (out-of-gamut) are
/// clamped to 0; brightness is normalised so that the [`WHITE_PERCENTILE`]
/// (99th percentile) of the per-pixel max(R, G, B) maps to 1, then values are
/// clamped to 1 (about 1 % of pixels may saturate; an all-zero cube renders
/// black); finally the sRGB transfer curve and rounding to 8 bits.
/// Deterministic. Errors if the wavelength count differs from the band count,
/// if the wavelengths are invalid, or if the cube holds NaN/±Inf.
pub fn pseudo_rgb(cube: &Cube, wavelengths_nm: &[f64]) -> Result<RgbImage> {
    if wavelengths_nm.len() != cube.bands() {
        return Err(CassiError::Shape {
            what: "wavelengths_nm".into(),
            got: format!("{} values", wavelengths_nm.len()),
            expected: format!("{} values (one per band of the cube)", cube.bands()),
        });
    }
    cube.check_finite("cube")?;
    let w = rgb_weights(wavelengths_nm)?;
    let n = cube.band_len();
    let mut lin = vec![0.0f64; 3 * n];
    for (k, ((&wr, &wg), &wb)) in w[0].iter().zip(&w[1]).zip(&w[2]).enumerate() {
        let band = cube.band(k);
        for (p, &s) in band.iter().enumerate() {
            let s = s as f64;
            lin[3 * p] += wr * s;
            lin[3 * p + 1] += wg * s;
            lin[3 * p + 2] += wb * s;
        }
    }
    lin.iter_mut().for_each(|v| *v = v.max(0.0));
    let mut peaks: Vec<f64> = lin
        .chunks_exact(3)
        .map(|px| px[0].max(px[1]).max(px[2]))
        .collect();
    let white = if peaks.is_empty() {
        0.0
    } else {
        let q = ((peaks.len() - 1) as f64 * WHITE_PERCENTILE).round() as usize;
        let (_, v, _) = peaks.select_nth_unstable_by(q, f64::total_cmp);
        *v
    };
    let gain = if white > 0.0 { 1.0 / white } else { 0.0 };
    let data = lin
        .iter()
        .map(|&v| (srgb_encode((v * gain).min(1.0)) * 255.0).round() as u8)
        .collect();
    Ok(RgbImage {
        rows: cube.rows(),
        cols: cube.cols(),
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::instrument::STANDARD_WAVELENGTHS_NM;

    /// A 2×3 cube with energy only in the band nearest `nm`, plus one dark pixel.
    fn mono(nm: f64) -> Cube {
        let wl = &STANDARD_WAVELENGTHS_NM;
        let k = (0..wl.len())
            .min_by(|&a, &b| (wl[a] - nm).abs().total_cmp(&(wl[b] - nm).abs()))
            .unwrap();
        let mut c = Cube::zeros(28, 2, 3);
        for p in 0..5 {
            c.set(k, p / 3, p % 3, 0.2 + 0.1 * p as f32);
        }
        c
    }

    fn dominant(img: &RgbImage, row: usize, col: usize) -> usize {
        let px = img.pixel(row, col);
        (0..3).max_by_key(|&c| px[c]).unwrap()
    }

    #[test]
    fn cmf_fit_matches_cie_table_at_landmarks() {
        // CIE 1931 2° table: ȳ(555) = 1.0000, x̄(600) = 1.0622, z̄(450) = 1.7721,
        // x̄(450) = 0.3362, ȳ(500) = 0.3230. The fit is good to a few per cent.
        let close = |a: f64, b: f64| (a - b).abs() < 0.03 * b.max(0.1);
        assert!(close(cie1931_xyz(555.0)[1], 1.0));
        assert!(close(cie1931_xyz(600.0)[0], 1.0622));
        assert!(close(cie1931_xyz(450.0)[2], 1.7721));
        assert!(close(cie1931_xyz(450.0)[0], 0.3362));
        assert!(close(cie1931_xyz(500.0)[1], 0.3230));
    }

    #[test]
    fn flat_spectrum_is_neutral_grey() {
        let mut c = Cube::zeros(28, 3, 4);
        for p in 0..12 {
            let v = 0.05 + 0.08 * p as f32;
            for k in 0..28 {
                c.set(k, p / 4, p % 4, v);
            }
        }
        let img = pseudo_rgb(&c, &STANDARD_WAVELENGTHS_NM).unwrap();
        let mut levels = Vec::new();
        for r in 0..3 {
            for col in 0..4 {
                let [red, g, b] = img.pixel(r, col);
                assert_eq!(
                    (red, g),
                    (g, b),
                    "pixel ({r},{col}) not grey: {red},{g},{b}"
                );
                levels.push(red);
            }
        }
        // Brighter flat spectra render brighter greys.
        assert!(levels.windows(2).all(|w| w[0] <= w[1]), "{levels:?}");
        assert!(levels[0] < levels[11]);
        // The weights of each channel sum to 1 (white balance).
        for wc in rgb_weights(&STANDARD_WAVELENGTHS_NM).unwrap() {
            assert!((wc.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn monochromatic_bands_render_their_hue() {
        for (nm, want) in [(460.0, 2usize), (550.0, 1), (640.0, 0)] {
            let img = pseudo_rgb(&mono(nm), &STANDARD_WAVELENGTHS_NM).unwrap();
            for p in 0..5 {
                let px = img.pixel(p / 3, p % 3);
                assert_eq!(dominant(&img, p / 3, p % 3), want, "{nm} nm → {px:?}");
                let others = (0..3).filter(|&c| c != want).map(|c| px[c]).max().unwrap();
                assert!(
                    px[want] > others + 40,
                    "{nm} nm not clearly dominant: {px:?}"
                );
            }
            // The pixel with no energy stays black.
            assert_eq!(img.pixel(1, 2), [0, 0, 0]);
        }
    }

    #[test]
    fn percentile_normalisation_and_determinism() {
        let mut c = Cube::zeros(28, 10, 10);
        for p in 0..100 {
            for k in 0..28 {
                c.set(
                    k,
                    p / 10,
                    p % 10,
                    (p as f32) / 100.0 * (1.0 + k as f32 / 28.0),
                );
            }
        }
        let a = pseudo_rgb(&c, &STANDARD_WAVELENGTHS_NM).unwrap();
        // Scaling the whole cube does not change the rendering (auto brightness).
        let mut c2 = c.clone();
        c2.as_mut_slice().iter_mut().for_each(|v| *v *= 7.5);
        let b = pseudo_rgb(&c2, &STANDARD_WAVELENGTHS_NM).unwrap();
        assert_eq!(a, b);
        assert_eq!(a, pseudo_rgb(&c, &STANDARD_WAVELENGTHS_NM).unwrap());
        // At most ~1 % of pixels (here: the brightest) reach 255 in their max channel.
        let saturated = (0..100)
            .filter(|&p| a.pixel(p / 10, p % 10).into_iter().max() == Some(255))
            .count();
        assert!((1..=2).contains(&saturated), "{saturated}");
        assert_eq!((a.rows, a.cols, a.data.len()), (10, 10, 300));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let c = Cube::zeros(3, 2, 2);
        assert!(matches!(
            pseudo_rgb(&c, &STANDARD_WAVELENGTHS_NM),
            Err(CassiError::Shape { .. })
        ));
        assert!(pseudo_rgb(&c, &[500.0, 490.0, 600.0]).is_err());
        let mut c = Cube::zeros(28, 2, 2);
        c.set(3, 1, 1, f32::NAN);
        assert!(matches!(
            pseudo_rgb(&c, &STANDARD_WAVELENGTHS_NM),
            Err(CassiError::NonFinite { .. })
        ));
        // All zeros renders black rather than dividing by zero.
        let img = pseudo_rgb(&Cube::zeros(28, 2, 2), &STANDARD_WAVELENGTHS_NM).unwrap();
        assert!(img.data.iter().all(|&v| v == 0));
    }
}
