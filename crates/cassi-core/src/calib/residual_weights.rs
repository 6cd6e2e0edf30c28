//! Residual weighting for the scene fit: weights that trust the frame
//! where a first fit left only noise and distrust it where it left
//! structure. The coarse scene cannot hold a scene's fine detail; what it
//! leaves is not noise but the scene's texture times the code, local and
//! far stronger than the noise where the scene is textured. Unweighted, the
//! fit's parameters lean toward whatever imitates it (a wider blur damps
//! the code's prediction there, `scene_fit_scan_blur_sigma_px*.json`).
//! The mask's code, which carries every parameter, runs everywhere, so
//! the regions with least texture still pin them. Weighting each pixel by
//! the inverse of the local residual energy (a generalised least squares
//! with the unexplained detail as heteroscedastic error, one reweighting
//! step of an M-estimator) leaves those regions the say.
//!
//! w = 1 / (e + e_floor), e = G_window ∗ r² the local mean squared
//! residual of the first fit, e_floor = its `floor_quantile` quantile
//! over the frame (the noise where the scene is flattest: no pixel gets
//! more than 1 / e_floor's trust), normalised to mean 1.

use serde::{Deserialize, Serialize};

use crate::error::{CassiError, Result};
use crate::optics::blur::GaussianBlur;

/// How the scene fit weights its residual.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ResidualWeighting {
    /// σ of the Gaussian the squared residual is averaged over, pixels.
    pub window_px: f64,
    /// The quantile of the local energy added to every pixel's (0–1).
    pub floor_quantile: f64,
}

impl Default for ResidualWeighting {
    fn default() -> Self {
        Self {
            window_px: 3.0,
            floor_quantile: 0.25,
        }
    }
}

impl ResidualWeighting {
    /// An error naming the field unless the settings can weight.
    pub fn check(&self) -> Result<()> {
        let bad = |name, value, reason: &str| {
            Err(CassiError::InvalidParameter {
                name,
                value,
                reason: reason.into(),
            })
        };
        if !(self.window_px.is_finite() && self.window_px > 0.0) {
            return bad(
                "residual_weighting.window_px",
                self.window_px,
                "the window must be a positive width in pixels",
            );
        }
        if !(self.floor_quantile > 0.0 && self.floor_quantile <= 1.0) {
            return bad(
                "residual_weighting.floor_quantile",
                self.floor_quantile,
                "the floor is a quantile in (0, 1]",
            );
        }
        Ok(())
    }

    /// √w per pixel of the `rows × cols` frame whose first fit left
    /// `residual` (all ones for a zero residual).
    pub(crate) fn root_weights(
        &self,
        residual: &[f32],
        rows: usize,
        cols: usize,
    ) -> Result<Vec<f32>> {
        self.check()?;
        let squared: Vec<f32> = residual.iter().map(|&r| r * r).collect();
        let mut local = vec![0.0f32; squared.len()];
        let mut tmp = vec![0.0f32; squared.len()];
        GaussianBlur::new(self.window_px, rows, cols)?.apply(&squared, &mut local, &mut tmp);
        let floor = quantile(&local, self.floor_quantile);
        if floor <= 0.0 {
            return Ok(vec![1.0; local.len()]);
        }
        let w: Vec<f64> = local
            .iter()
            .map(|&e| 1.0 / (e.max(0.0) + floor) as f64)
            .collect();
        let mean = w.iter().sum::<f64>() / w.len().max(1) as f64;
        Ok(w.iter().map(|&v| (v / mean).sqrt() as f32).collect())
    }
}

/// The `q` quantile of `values` (nearest rank).
fn quantile(values: &[f32], q: f64) -> f32 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1;
    let (_, v, _) = sorted.select_nth_unstable_by(rank, f32::total_cmp);
    *v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_textured_patch_loses_weight_and_a_quiet_frame_keeps_it() {
        let (rows, cols) = (40, 40);
        let mut rng = crate::rng::Rng::new(7);
        let mut r: Vec<f32> = (0..rows * cols)
            .map(|_| 0.01 * (rng.uniform() as f32 - 0.5))
            .collect();
        // a 10 × 10 patch of structure 30× the noise
        for i in 5..15 {
            for j in 5..15 {
                r[i * cols + j] *= 30.0;
            }
        }
        let w = ResidualWeighting::default()
            .root_weights(&r, rows, cols)
            .unwrap();
        let inside = w[10 * cols + 10].powi(2);
        let outside = w[30 * cols + 30].powi(2);
        assert!(inside < outside / 20.0, "patch {inside}, quiet {outside}");
        let mean: f32 = w.iter().map(|v| v * v).sum::<f32>() / w.len() as f32;
        assert!((mean - 1.0).abs() < 1e-4, "mean weight {mean}");
        let flat = ResidualWeighting::default()
            .root_weights(&vec![0.0; rows * cols], rows, cols)
            .unwrap();
        assert!(flat.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn bad_settings_name_their_field() {
        let bad = ResidualWeighting {
            window_px: 0.0,
            ..ResidualWeighting::default()
        };
        let e = bad.root_weights(&[0.0; 4], 2, 2).unwrap_err().to_string();
        assert!(e.contains("window_px"), "{e}");
        let bad = ResidualWeighting {
            floor_quantile: 1.5,
            ..ResidualWeighting::default()
        };
        let e = bad.check().unwrap_err().to_string();
        assert!(e.contains("floor_quantile"), "{e}");
    }
}
