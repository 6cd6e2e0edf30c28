//! Detector noise: Poisson shot noise at a photon budget plus Gaussian read
//! noise, seeded and reproducible on every platform and thread count.
//!
//! Units: the measurement is scaled so that its maximum equals
//! `photon_peak` photo-electrons; shot noise is Poisson in those counts and
//! `read_noise` is the Gaussian σ **in the same counts (electrons)**; the
//! result is scaled back and clamped at 0 (a detector reads no negative light).
//! With the defaults (peak 1e5, σ 0.01 e⁻, the paper's values) shot noise
//! dominates: ≈ 0.3 % of the peak at the peak.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cube::Measurement;
use crate::error::{CassiError, Result};
use crate::rng::Rng;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NoiseModel {
    /// Photo-electrons at the measurement's maximum; `None` = no shot noise.
    pub photon_peak: Option<f64>,
    /// Gaussian read-noise σ in electrons (counts at the `photon_peak` scale;
    /// relative to a peak of 1 when there is no shot noise).
    pub read_noise: f64,
    pub seed: u64,
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self {
            photon_peak: Some(1e5),
            read_noise: 0.01,
            seed: 0,
        }
    }
}

impl NoiseModel {
    pub fn validate(&self) -> Result<()> {
        if let Some(p) = self.photon_peak
            && !(p.is_finite() && p > 0.0 && p <= 1e12)
        {
            return Err(CassiError::InvalidParameter {
                name: "photon_peak",
                value: p,
                reason: "the photon count at the peak must be in (0, 1e12]".into(),
            });
        }
        if !(self.read_noise.is_finite() && self.read_noise >= 0.0) {
            return Err(CassiError::InvalidParameter {
                name: "read_noise",
                value: self.read_noise,
                reason: "the read-noise σ must be a finite number ≥ 0 (electrons)".into(),
            });
        }
        Ok(())
    }

    /// A noisy copy of `clean` (values ≥ 0; its maximum sets the count scale).
    pub fn apply(&self, clean: &Measurement) -> Result<Measurement> {
        self.validate()?;
        clean.check_finite("clean measurement")?;
        let ymax = clean.max().max(0.0) as f64;
        let peak = self.photon_peak.unwrap_or(1.0);
        // counts = y · scale; an all-dark frame gets read noise at unit scale
        let scale = if ymax > 0.0 { peak / ymax } else { 1.0 };
        let mut out = clean.clone();
        let cols = out.cols().max(1);
        out.as_mut_slice()
            .par_chunks_mut(cols)
            .enumerate()
            .for_each(|(row, values)| {
                let mut rng = Rng::stream(self.seed, row as u64);
                for v in values.iter_mut() {
                    let mean = (*v as f64).max(0.0) * scale;
                    let mut counts = match self.photon_peak {
                        Some(_) => poisson(&mut rng, mean) as f64,
                        None => mean,
                    };
                    if self.read_noise > 0.0 {
                        counts += self.read_noise * rng.normal();
                    }
                    *v = (counts.max(0.0) / scale) as f32;
                }
            });
        Ok(out)
    }
}

/// An exact Poisson(λ) draw: multiplication method below λ = 10, Hörmann's
/// PTRS transformed rejection above (W. Hörmann, 1993). libm throughout, so
/// draws are identical on every platform.
pub fn poisson(rng: &mut Rng, lambda: f64) -> u64 {
    if lambda <= 0.0 {
        return 0;
    }
    if lambda < 10.0 {
        let limit = libm::exp(-lambda);
        let mut k = 0u64;
        let mut p = rng.uniform();
        while p > limit {
            k += 1;
            p *= rng.uniform();
        }
        return k;
    }
    let slam = libm::sqrt(lambda);
    let loglam = libm::log(lambda);
    let b = 0.931 + 2.53 * slam;
    let a = -0.059 + 0.02483 * b;
    let inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
    let vr = 0.9277 - 3.6224 / (b - 2.0);
    loop {
        let u = rng.uniform() - 0.5;
        let v = rng.uniform();
        let us = 0.5 - u.abs();
        let k = libm::floor((2.0 * a / us + b) * u + lambda + 0.43);
        if us >= 0.07 && v <= vr {
            return k as u64;
        }
        if k < 0.0 || (us < 0.013 && v > us) {
            continue;
        }
        if libm::log(v) + libm::log(inv_alpha) - libm::log(a / (us * us) + b)
            <= -lambda + k * loglam - libm::lgamma(k + 1.0)
        {
            return k as u64;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cube::Frame;

    fn moments(lambda: f64, n: usize) -> (f64, f64) {
        let mut rng = Rng::new(lambda.to_bits());
        let draws: Vec<f64> = (0..n).map(|_| poisson(&mut rng, lambda) as f64).collect();
        let mean = draws.iter().sum::<f64>() / n as f64;
        let var = draws.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n as f64;
        (mean, var)
    }

    #[test]
    fn poisson_mean_equals_variance_equals_lambda() {
        for lambda in [0.3, 4.0, 9.9, 10.0, 37.5, 1e3, 1e5] {
            let n = 200_000;
            let (mean, var) = moments(lambda, n);
            let se = (lambda / n as f64).sqrt();
            assert!((mean - lambda).abs() < 5.0 * se, "λ={lambda}: mean {mean}");
            assert!((var / lambda - 1.0).abs() < 0.03, "λ={lambda}: var {var}");
        }
        // P(0) for small λ is exp(−λ)
        let mut rng = Rng::new(1);
        let zeros = (0..100_000).filter(|_| poisson(&mut rng, 0.5) == 0).count() as f64 / 1e5;
        assert!((zeros - (-0.5f64).exp()).abs() < 0.005);
    }

    #[test]
    fn shot_noise_scales_with_the_photon_budget_and_is_reproducible() {
        let clean = Frame::from_vec(64, 64, vec![0.5; 64 * 64]).unwrap();
        let model = NoiseModel {
            photon_peak: Some(1e4),
            read_noise: 0.0,
            seed: 3,
        };
        let a = model.apply(&clean).unwrap();
        assert_eq!(a, model.apply(&clean).unwrap());
        assert_ne!(a, NoiseModel { seed: 4, ..model }.apply(&clean).unwrap());
        // every pixel is the max, so counts ~ Poisson(1e4): relative σ = 1 %
        let n = a.as_slice().len() as f64;
        let mean = a.as_slice().iter().map(|&v| v as f64).sum::<f64>() / n;
        let sd = (a
            .as_slice()
            .iter()
            .map(|&v| (v as f64 - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!((mean - 0.5).abs() < 0.001, "{mean}");
        assert!((sd / 0.5 - 0.01).abs() < 0.0005, "{sd}");
    }

    #[test]
    fn read_noise_is_in_electrons_and_output_is_non_negative() {
        let clean = Frame::from_vec(100, 100, vec![1.0; 10_000]).unwrap();
        let model = NoiseModel {
            photon_peak: None,
            read_noise: 0.1,
            seed: 0,
        };
        let y = model.apply(&clean).unwrap();
        let n = 10_000.0;
        let mean = y.as_slice().iter().map(|&v| v as f64).sum::<f64>() / n;
        let sd = (y
            .as_slice()
            .iter()
            .map(|&v| (v as f64 - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!((sd - 0.1).abs() < 0.005, "{sd}");
        let dark = Frame::zeros(10, 10);
        assert!(
            model
                .apply(&dark)
                .unwrap()
                .as_slice()
                .iter()
                .all(|&v| v >= 0.0)
        );
    }

    #[test]
    fn invalid_noise_parameters_are_rejected() {
        let f = Frame::zeros(2, 2);
        assert!(
            NoiseModel {
                photon_peak: Some(0.0),
                ..Default::default()
            }
            .apply(&f)
            .is_err()
        );
        assert!(
            NoiseModel {
                read_noise: -1.0,
                ..Default::default()
            }
            .apply(&f)
            .is_err()
        );
        assert!(
            NoiseModel {
                read_noise: f64::NAN,
                ..Default::default()
            }
            .apply(&f)
            .is_err()
        );
    }
}
