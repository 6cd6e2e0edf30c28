//! Meaning checks: data with the right shape that still cannot be a CASSI
//! input (a measurement with no light, a mask with no code, a mismatch that
//! moves the mask off the detector). Shapes and finiteness are checked where
//! the data are built; these checks say why the *values* make no sense.

use crate::cube::{Mask, Measurement};
use crate::error::{CassiError, Result};
use crate::params::Mismatch;

/// How far below zero a measurement may go, relative to its maximum: dark-
/// frame subtraction and read noise leave small negative values, a signed or
/// inverted image does not.
pub const NEGATIVE_SLACK: f32 = 0.1;

/// Refuses a measurement that holds no light (every value ≤ 0), NaN/±Inf,
/// or values negative beyond noise (below −[`NEGATIVE_SLACK`] × its maximum).
pub fn validate_measurement(measurement: &Measurement, what: &str) -> Result<()> {
    measurement.check_finite(what)?;
    let (lo, hi) = measurement.min_max();
    let meaningless = |reason: String| CassiError::Meaningless {
        what: what.to_string(),
        reason,
    };
    if hi <= 0.0 {
        let detail = if lo == 0.0 && hi == 0.0 {
            "every value is 0".to_string()
        } else {
            format!("every value is ≤ 0 (range [{lo}, {hi}])")
        };
        return Err(meaningless(format!(
            "no light reached the detector: {detail}; a measurement is a photon count"
        )));
    }
    if lo < -NEGATIVE_SLACK * hi {
        return Err(meaningless(format!(
            "values go down to {lo} against a maximum of {hi}; a measurement is a photon \
             count (≥ 0; noise may leave values down to −{} × the maximum)",
            NEGATIVE_SLACK
        )));
    }
    Ok(())
}

/// Whether a mask codes anything.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MaskCode {
    /// Open and closed (or gray) pixels: a coded aperture.
    Coded,
    /// Every pixel has this one transmission: light passes, but nothing is
    /// coded (calibration has nothing to lock on to).
    Uniform(f32),
}

/// Refuses a mask that lets no light through; tells a coded mask from a
/// uniform one (all open, or one gray level), which a caller may accept
/// (simulation) or refuse (calibration).
pub fn mask_code(mask: &Mask, what: &str) -> Result<MaskCode> {
    let (lo, hi) = mask.min_max();
    if hi <= 0.0 {
        return Err(CassiError::Meaningless {
            what: what.to_string(),
            reason: format!(
                "every pixel is closed ({}×{} mask, all values ≤ 0): no light reaches the detector",
                mask.rows(),
                mask.cols()
            ),
        });
    }
    Ok(if hi - lo <= f32::EPSILON * hi {
        MaskCode::Uniform(hi)
    } else {
        MaskCode::Coded
    })
}

/// Refuses a mismatch that moves the mask (rows × cols) entirely off itself:
/// |dx| ≥ cols or |dy| ≥ rows leaves no pixel of the mask over the scene.
pub fn validate_mismatch_for_mask(mismatch: &Mismatch, rows: usize, cols: usize) -> Result<()> {
    mismatch.validate()?;
    for (name, value, limit, axis) in [
        ("dx", mismatch.dx, cols, "width"),
        ("dy", mismatch.dy, rows, "height"),
    ] {
        if value.abs() >= limit as f64 {
            return Err(CassiError::InvalidParameter {
                name,
                value,
                reason: format!(
                    "|{name}| must be below the mask {axis} ({limit} px): a shift that large \
                     moves the whole mask off the scene"
                ),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cube::Frame;

    fn frame(values: &[f32]) -> Frame {
        Frame::from_vec(2, values.len() / 2, values.to_vec()).unwrap()
    }

    #[test]
    fn measurements_without_light_or_far_below_zero_are_refused() {
        assert!(validate_measurement(&frame(&[0.0, 1.0, 2.0, 0.5]), "m").is_ok());
        // read noise around zero is fine
        assert!(validate_measurement(&frame(&[-0.05, 1.0, 2.0, 0.0]), "m").is_ok());
        let zero = validate_measurement(&frame(&[0.0; 4]), "m.npy").unwrap_err();
        assert!(zero.to_string().contains("every value is 0"), "{zero}");
        assert!(zero.to_string().starts_with("m.npy"), "{zero}");
        let negative = validate_measurement(&frame(&[-1.0, -2.0, -0.5, -3.0]), "m").unwrap_err();
        assert!(negative.to_string().contains("≤ 0"), "{negative}");
        let signed = validate_measurement(&frame(&[-1.0, 2.0, 0.5, 3.0]), "m").unwrap_err();
        assert!(signed.to_string().contains("down to -1"), "{signed}");
        let nan = validate_measurement(&frame(&[f32::NAN, 2.0, 0.5, 3.0]), "m").unwrap_err();
        assert!(matches!(nan, CassiError::NonFinite { .. }), "{nan}");
    }

    #[test]
    fn closed_masks_are_refused_and_uniform_ones_told_apart() {
        assert_eq!(
            mask_code(&frame(&[0.0, 1.0, 1.0, 0.0]), "mask").unwrap(),
            MaskCode::Coded
        );
        assert_eq!(
            mask_code(&frame(&[1.0; 4]), "mask").unwrap(),
            MaskCode::Uniform(1.0)
        );
        assert_eq!(
            mask_code(&frame(&[0.5; 4]), "mask").unwrap(),
            MaskCode::Uniform(0.5)
        );
        let e = mask_code(&frame(&[0.0; 4]), "mask.npy").unwrap_err();
        assert!(e.to_string().contains("every pixel is closed"), "{e}");
    }

    #[test]
    fn shifts_beyond_the_mask_are_refused() {
        let mut m = Mismatch::nominal(2.0);
        assert!(validate_mismatch_for_mask(&m, 32, 48).is_ok());
        m.dx = 47.9;
        assert!(validate_mismatch_for_mask(&m, 32, 48).is_ok());
        m.dx = 1e9;
        let e = validate_mismatch_for_mask(&m, 32, 48)
            .unwrap_err()
            .to_string();
        assert!(e.contains("dx") && e.contains("48 px"), "{e}");
        m.dx = 0.0;
        m.dy = -32.0;
        let e = validate_mismatch_for_mask(&m, 32, 48)
            .unwrap_err()
            .to_string();
        assert!(e.contains("dy") && e.contains("32 px"), "{e}");
    }
}
