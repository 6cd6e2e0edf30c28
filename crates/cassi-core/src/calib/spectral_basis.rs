//! A coarse scene's spectra from the measurement itself: the principal
//! spectra of GAP-TV's reconstruction at the fit's ψ, in place of evenly
//! spaced spectral nodes (a probe of the fine pass, [`SpectralBasis`]).
//!
//! Why: told the true scene through the 6 evenly spaced nodes, the
//! scene-known fit already slides along dx–a1 on scenes with sharp spectra
//! (stop 58: peppers dx −0.06 px; through 10 nodes −0.01), and 10 nodes
//! let the blind fit slide on random poses. A scene's own principal
//! spectra hold its spectra as closely with 6 as 10 evenly spaced nodes do
//! (CAVE, the true cubes, relative RMS left out: peppers 1.1 % against
//! 1.3 %, 4.2 % with 6 nodes; `bench/spectral_basis_fit.py`), with no more
//! freedom than 6. Measured blind (stop 60, tuning half,
//! `bench/results/default_stop60/`): all six 9 → 10 of 30 random poses,
//! dx within 16 → 16, dx moving both ways — not adopted.

use serde::{Deserialize, Serialize};

use super::score::{CalibrationProblem, gap_tv_reconstruction};
use super::uncertainty::invert_positive_definite;
use crate::error::{CassiError, Result};
use crate::params::Mismatch;

/// The principal spectra of GAP-TV's reconstruction at the pass's start.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpectralBasis {
    /// How many spectra (the scene's spectral freedom).
    pub components: usize,
    /// GAP-TV's iterations for the reconstruction.
    pub gap_iterations: usize,
}

impl SpectralBasis {
    /// Its settings for a cube of `bands` bands, named when out of range
    /// (a settings file's, say).
    pub(crate) fn check(&self, bands: usize) -> Result<()> {
        if self.components == 0 || self.components > bands || self.gap_iterations == 0 {
            return Err(CassiError::InvalidParameter {
                name: "fine_pass.spectral_basis",
                value: self.components as f64,
                reason: format!(
                    "1 to the cube's {bands} principal spectra, from 1 or more GAP-TV iterations"
                ),
            });
        }
        Ok(())
    }

    /// The basis' spectra (bands × components, row-major) at `at`.
    pub(crate) fn spectra(
        &self,
        problem: &CalibrationProblem<'_>,
        at: &Mismatch,
    ) -> Result<Vec<f64>> {
        let bands = problem.bands();
        self.check(bands)?;
        let cube = gap_tv_reconstruction(problem, at, self.gap_iterations)?;
        Ok(principal_spectra(cube.as_slice(), bands, self.components))
    }
}

/// The `m` leading eigenvectors (bands × m, row-major) of Σ_p x_p x_pᵀ over
/// the pixels' spectra x_p of `cube` (bands × pixels): the uncentred
/// principal spectra, the mean spectrum's direction first. Each column's
/// sign makes its sum non-negative.
pub(crate) fn principal_spectra(cube: &[f32], bands: usize, m: usize) -> Vec<f64> {
    let plane = cube.len() / bands.max(1);
    let mut gram = vec![0.0f64; bands * bands];
    for i in 0..bands {
        let a = &cube[i * plane..(i + 1) * plane];
        for j in 0..=i {
            let b = &cube[j * plane..(j + 1) * plane];
            let v: f64 = a.iter().zip(b).map(|(&x, &y)| x as f64 * y as f64).sum();
            gram[i * bands + j] = v;
            gram[j * bands + i] = v;
        }
    }
    let (values, vectors) = symmetric_eigen(gram, bands);
    let mut order: Vec<usize> = (0..bands).collect();
    order.sort_by(|&a, &b| values[b].total_cmp(&values[a]));
    let mut out = vec![0.0f64; bands * m];
    for (j, &c) in order.iter().take(m).enumerate() {
        let sum: f64 = (0..bands).map(|k| vectors[k * bands + c]).sum();
        let sign = if sum < 0.0 { -1.0 } else { 1.0 };
        for k in 0..bands {
            out[k * m + j] = sign * vectors[k * bands + c];
        }
    }
    out
}

/// The least-squares projector (BᵀB)⁻¹Bᵀ (m × bands, row-major) of B =
/// `spectra` (bands × m); B's columns must be independent.
pub(crate) fn projector(spectra: &[f64], bands: usize, m: usize) -> Vec<f64> {
    let mut btb = vec![0.0f64; m * m];
    for i in 0..m {
        for j in 0..m {
            btb[i * m + j] = (0..bands)
                .map(|k| spectra[k * m + i] * spectra[k * m + j])
                .sum();
        }
    }
    let inv = invert_positive_definite(&btb, m)
        .expect("projector: the basis' spectra are linearly independent");
    let mut p = vec![0.0f64; m * bands];
    for j in 0..m {
        for k in 0..bands {
            p[j * bands + k] = (0..m).map(|i| inv[j * m + i] * spectra[k * m + i]).sum();
        }
    }
    p
}

/// Eigenvalues and eigenvectors (columns of the n × n row-major matrix) of
/// the symmetric `a`, by cyclic Jacobi rotations.
fn symmetric_eigen(mut a: Vec<f64>, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut v = vec![0.0f64; n * n];
    (0..n).for_each(|i| v[i * n + i] = 1.0);
    let scale: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i * n + j] * a[i * n + j])
            .sum();
        if off.sqrt() <= 1e-14 * scale {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[k * n + p], a[k * n + q]);
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| a[i * n + i]).collect(), v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cube whose spectra are mixtures of three known spectra: its first
    /// three principal spectra span them (every spectrum's projection
    /// onto them is itself), the eigenvectors are orthonormal, and two
    /// spectra leave the third's share out.
    #[test]
    fn the_principal_spectra_span_a_cube_of_three_spectra() {
        let bands = 12;
        let spectra: [Vec<f64>; 3] = [
            (0..bands).map(|k| 1.0 + 0.1 * k as f64).collect(),
            (0..bands).map(|k| ((k as f64) * 0.7).sin()).collect(),
            (0..bands).map(|k| if k > 7 { 1.0 } else { 0.0 }).collect(),
        ];
        let plane = 200;
        let mut cube = vec![0.0f32; bands * plane];
        for p in 0..plane {
            let w = [
                1.0 + (p % 7) as f64,
                ((p * 13) % 11) as f64 / 5.0,
                ((p * 7) % 5) as f64,
            ];
            for k in 0..bands {
                cube[k * plane + p] = (0..3).map(|s| w[s] * spectra[s][k]).sum::<f64>() as f32;
            }
        }
        let residual_share = |m: usize| {
            let b = principal_spectra(&cube, bands, m);
            let proj = projector(&b, bands, m);
            for i in 0..m {
                for j in 0..m {
                    let dot: f64 = (0..bands).map(|k| b[k * m + i] * b[k * m + j]).sum();
                    assert!((dot - f64::from(i == j)).abs() < 1e-9, "{i} {j}: {dot}");
                }
            }
            let (mut left, mut total) = (0.0f64, 0.0f64);
            for p in 0..plane {
                let x: Vec<f64> = (0..bands).map(|k| cube[k * plane + p] as f64).collect();
                let z: Vec<f64> = (0..m)
                    .map(|j| (0..bands).map(|k| proj[j * bands + k] * x[k]).sum())
                    .collect();
                for k in 0..bands {
                    let fit: f64 = (0..m).map(|j| b[k * m + j] * z[j]).sum();
                    left += (x[k] - fit).powi(2);
                    total += x[k] * x[k];
                }
            }
            left / total
        };
        assert!(residual_share(3) < 1e-10, "{}", residual_share(3));
        assert!(residual_share(2) > 1e-4, "{}", residual_share(2));
    }

    /// Jacobi's eigenpairs satisfy A v = λ v on a matrix with a repeated
    /// eigenvalue.
    #[test]
    fn jacobi_gives_eigenpairs() {
        let n = 5;
        let a: Vec<f64> = (0..n * n)
            .map(|i| {
                let (r, c) = (i / n, i % n);
                if r == c {
                    2.0 + r as f64 % 2.0
                } else {
                    0.3 / (1.0 + (r + c) as f64)
                }
            })
            .collect();
        let (values, vectors) = symmetric_eigen(a.clone(), n);
        for c in 0..n {
            for r in 0..n {
                let av: f64 = (0..n).map(|k| a[r * n + k] * vectors[k * n + c]).sum();
                assert!((av - values[c] * vectors[r * n + c]).abs() < 1e-10);
            }
        }
    }
}
