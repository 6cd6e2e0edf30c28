//! Smooth reflectance spectra and illuminants, evaluated at any wavelength.
//!
//! Real surface reflectances in the visible are broad and smooth: pigments
//! and dyes are sums of wide absorption bands (tens of nm), many colourants
//! show a sigmoid "edge" (yellows, oranges, reds), vegetation has a green
//! bump and a steep red edge near 700 nm, skin shows the haemoglobin
//! double dip near 542/577 nm. Every family here is built from broad
//! Gaussians and logistic edges with widths of at least 8 nm, so a spectrum
//! sampled at CASSI band spacing (4–12 nm) is smooth, yet families differ in
//! shape (not only in brightness), which gives regions distinct spectral
//! angles. All transcendental functions go through `libm`, so values are the
//! same on every platform.

use crate::rng::Rng;

/// A parametric reflectance spectrum, reflectance in [0.01, 0.98].
#[derive(Debug, Clone, PartialEq)]
pub enum Reflectance {
    /// Nearly grey: `level` with a linear `tilt` per 100 nm about 550 nm.
    Neutral { level: f64, tilt: f64 },
    /// `base` plus Gaussian bands `(amplitude, centre nm, sigma nm)`;
    /// negative amplitudes are absorption dips.
    Bands {
        base: f64,
        bands: Vec<(f64, f64, f64)>,
    },
    /// Logistic edge from `lo` (short λ) to `hi` (long λ) at `centre` nm with
    /// `width` nm (hi < lo gives a falling edge: blues and cyans).
    Edge {
        lo: f64,
        hi: f64,
        centre: f64,
        width: f64,
    },
    /// Green leaf: low blue, a green bump near 550 nm, chlorophyll absorption
    /// near 670 nm and the sigmoid red edge near 700–720 nm; `gain` scales it.
    Vegetation { gain: f64, red_edge_nm: f64 },
    /// Skin-like: rising toward red with the haemoglobin dips at 542/577 nm.
    Skin { level: f64, dip: f64 },
}

fn gauss(x: f64, mu: f64, sigma: f64) -> f64 {
    let z = (x - mu) / sigma;
    libm::exp(-0.5 * z * z)
}

fn logistic(x: f64, centre: f64, width: f64) -> f64 {
    1.0 / (1.0 + libm::exp(-(x - centre) / width))
}

impl Reflectance {
    /// Reflectance at wavelength `nm`, clamped to [0.01, 0.98].
    pub fn eval(&self, nm: f64) -> f64 {
        let r = match self {
            Reflectance::Neutral { level, tilt } => level + tilt * (nm - 550.0) / 100.0,
            Reflectance::Bands { base, bands } => {
                base + bands
                    .iter()
                    .map(|&(a, mu, s)| a * gauss(nm, mu, s))
                    .sum::<f64>()
            }
            Reflectance::Edge {
                lo,
                hi,
                centre,
                width,
            } => lo + (hi - lo) * logistic(nm, *centre, *width),
            Reflectance::Vegetation { gain, red_edge_nm } => {
                let v = 0.045 + 0.085 * gauss(nm, 552.0, 32.0) - 0.03 * gauss(nm, 672.0, 18.0)
                    + 0.02 * gauss(nm, 450.0, 25.0)
                    + 0.45 * logistic(nm, *red_edge_nm, 11.0);
                gain * v
            }
            Reflectance::Skin { level, dip } => {
                level * (0.45 + 0.55 * logistic(nm, 600.0, 18.0))
                    - dip * (gauss(nm, 542.0, 13.0) + gauss(nm, 577.0, 11.0))
            }
        };
        r.clamp(0.01, 0.98)
    }

    /// Samples the spectrum at `wavelengths_nm`.
    pub fn sample(&self, wavelengths_nm: &[f64]) -> Vec<f64> {
        wavelengths_nm.iter().map(|&w| self.eval(w)).collect()
    }

    /// A random material from a mix of families: coloured pigments (single
    /// or double broad peaks), dyes with an absorption dip, sigmoid edges
    /// rising (yellow–red) or falling (blue–cyan), vegetation, skin and
    /// near-greys. `family` picks one family deterministically when `Some`
    /// (0..=7), else the family is drawn too.
    pub fn random(rng: &mut Rng, family: Option<u32>) -> Self {
        let f = family.unwrap_or_else(|| rng.below(8) as u32) % 8;
        match f {
            0 => Reflectance::Edge {
                lo: rng.uniform_in(0.03, 0.18),
                hi: rng.uniform_in(0.5, 0.9),
                centre: rng.uniform_in(495.0, 615.0),
                width: rng.uniform_in(9.0, 25.0),
            },
            1 => Reflectance::Edge {
                lo: rng.uniform_in(0.45, 0.85),
                hi: rng.uniform_in(0.04, 0.2),
                centre: rng.uniform_in(480.0, 560.0),
                width: rng.uniform_in(12.0, 30.0),
            },
            2 => Reflectance::Bands {
                base: rng.uniform_in(0.03, 0.12),
                bands: vec![(
                    rng.uniform_in(0.3, 0.7),
                    rng.uniform_in(440.0, 640.0),
                    rng.uniform_in(25.0, 55.0),
                )],
            },
            3 => Reflectance::Bands {
                base: rng.uniform_in(0.03, 0.1),
                bands: vec![
                    (
                        rng.uniform_in(0.25, 0.6),
                        rng.uniform_in(430.0, 480.0),
                        rng.uniform_in(20.0, 40.0),
                    ),
                    (
                        rng.uniform_in(0.25, 0.7),
                        rng.uniform_in(600.0, 680.0),
                        rng.uniform_in(25.0, 50.0),
                    ),
                ],
            },
            4 => Reflectance::Bands {
                base: rng.uniform_in(0.45, 0.85),
                bands: vec![(
                    -rng.uniform_in(0.25, 0.55),
                    rng.uniform_in(505.0, 600.0),
                    rng.uniform_in(22.0, 45.0),
                )],
            },
            5 => Reflectance::Vegetation {
                gain: rng.uniform_in(1.2, 2.4),
                red_edge_nm: rng.uniform_in(695.0, 720.0),
            },
            6 => Reflectance::Skin {
                level: rng.uniform_in(0.35, 0.7),
                dip: rng.uniform_in(0.03, 0.07),
            },
            _ => Reflectance::Neutral {
                level: rng.uniform_in(0.12, 0.8),
                tilt: rng.uniform_in(-0.06, 0.06),
            },
        }
    }
}

/// Relative spectral power of a blackbody at `kelvin` (Planck's law), at
/// wavelength `nm`; unnormalised (divide by a reference value).
pub fn blackbody(nm: f64, kelvin: f64) -> f64 {
    // c2 = h c / k in nm·K.
    const C2: f64 = 1.438_776_877e7;
    let l = nm / 1000.0; // µm keeps the magnitudes tame
    1.0 / (l * l * l * l * l * (libm::exp(C2 / (nm * kelvin)) - 1.0))
}

/// Blackbody SPD at `kelvin` sampled at `wavelengths_nm`, normalised so its
/// maximum over the samples is 1.
pub fn blackbody_spd(wavelengths_nm: &[f64], kelvin: f64) -> Vec<f64> {
    let v: Vec<f64> = wavelengths_nm
        .iter()
        .map(|&w| blackbody(w, kelvin))
        .collect();
    let m = v.iter().copied().fold(0.0, f64::max);
    v.into_iter().map(|x| x / m).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blackbody_peaks_follow_wien() {
        // Wien: λ_max = 2.898e6 nm·K / T → 5500 K peaks at ≈ 527 nm.
        let wl: Vec<f64> = (400..=700).map(f64::from).collect();
        let s = blackbody_spd(&wl, 5500.0);
        let imax = s
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap()
            .0;
        assert!((wl[imax] - 527.0).abs() <= 1.5, "{}", wl[imax]);
        // A warm 3000 K source rises toward red over the visible.
        let w = blackbody_spd(&[450.0, 650.0], 3000.0);
        assert!(w[1] > 2.0 * w[0]);
    }

    #[test]
    fn families_are_in_range_and_shaped_as_named() {
        let mut rng = Rng::new(5);
        for fam in 0..8 {
            for _ in 0..20 {
                let r = Reflectance::random(&mut rng, Some(fam));
                for nm in (400..=720).step_by(5) {
                    let v = r.eval(f64::from(nm));
                    assert!((0.01..=0.98).contains(&v), "{r:?} at {nm}: {v}");
                }
            }
        }
        let leaf = Reflectance::Vegetation {
            gain: 1.0,
            red_edge_nm: 705.0,
        };
        assert!(leaf.eval(550.0) > 1.5 * leaf.eval(460.0));
        assert!(leaf.eval(550.0) > 1.5 * leaf.eval(650.0));
        assert!(leaf.eval(760.0) > 3.0 * leaf.eval(550.0), "red edge");
        let skin = Reflectance::Skin {
            level: 0.6,
            dip: 0.05,
        };
        // Haemoglobin dips: the spectrum is locally concave up at 542 and 577 nm.
        for nm in [542.0, 577.0] {
            assert!(skin.eval(nm - 12.0) + skin.eval(nm + 12.0) > 2.0 * skin.eval(nm) + 0.01);
        }
    }
}
