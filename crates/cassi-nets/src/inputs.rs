//! The network inputs of the MST toolbox (caiyuanhao1998/MST, its
//! `template.py` and `test.py`), built from a raw CASSI measurement and the
//! coded aperture: H (`input_setting 'H'`), the measurement scaled and
//! shifted back into a cube, and Phi (`input_mask 'Phi'`), the mask shifted
//! per band.

use cassi_core::optics::warp_mask;
use cassi_core::recon::fit_width;
use cassi_core::{Mask, MaskPose, Measurement};

use crate::error::{NetError, Result};
use crate::tensor::Tensor;

/// The networks' H and Phi for an instrument whose mask sits at a known
/// pose, and how the measurement was fitted.
#[derive(Debug, Clone)]
pub struct PosedInputs {
    pub h: Tensor,
    pub phi: Tensor,
    /// (measurement columns, expected columns) when they differed and the
    /// measurement was cropped or zero-padded on the right (a drifted
    /// dispersion makes it a column or two wider or narrower).
    pub width_fitted: Option<(usize, usize)>,
}

/// [`toolbox_inputs`] with Phi built from the mask as the instrument holds
/// it: `nominal_mask` moved by `pose` (dx, dy, θ; cassi-core's
/// [`warp_mask`], the same warp the solvers' operator uses), so the mask a
/// network is guided by is the nominal, the calibrated or the true one.
/// The dispersion stays the networks' trained `step` per band: a
/// calibration's a1 and α are not used (the networks were trained on
/// step-2, straight dispersion). `y` is fitted on the right to
/// `W + step·(bands − 1)` columns, as the solvers fit it to their model.
pub fn posed_inputs(
    y: &Measurement,
    nominal_mask: &Mask,
    pose: &MaskPose,
    bands: usize,
    step: usize,
) -> Result<PosedInputs> {
    pose.validate()?;
    let (rows, w) = nominal_mask.shape();
    if y.rows() != rows {
        return Err(NetError::Input {
            what: "measurement".into(),
            got: format!("{}×{}", y.rows(), y.cols()),
            expected: format!("{rows} rows (the mask is {rows}×{w})"),
        });
    }
    let wy = w + step * bands.saturating_sub(1);
    let width_fitted = (y.cols() != wy).then_some((y.cols(), wy));
    let fitted;
    let y = if width_fitted.is_some() {
        fitted = fit_width(y, wy);
        &fitted
    } else {
        y
    };
    let mask = warp_mask(nominal_mask, pose);
    let (h, phi) = toolbox_inputs(y, &mask, bands, step)?;
    Ok(PosedInputs {
        h,
        phi,
        width_fitted,
    })
}

/// H and Phi for `bands` bands dispersed `step` columns apart:
/// * H (1, L, rows, W) with H[c, r, j] = ys[r, step·c + j], where
///   ys = (y / L) · 2 in f32, division first (as the toolbox; `y · (2/L)`
///   differs in the last bit);
/// * Phi (1, L, rows, W + step·(L−1)) with Phi[c, r, step·c + j] = mask[r, j].
///
/// The measurement must be `rows × (W + step·(L−1))` for a `rows × W` mask.
pub fn toolbox_inputs(
    y: &Measurement,
    mask: &Mask,
    bands: usize,
    step: usize,
) -> Result<(Tensor, Tensor)> {
    let (rows, w) = mask.shape();
    let wy = w + step * bands.saturating_sub(1);
    if bands == 0 || rows == 0 || w == 0 {
        return Err(NetError::Input {
            what: "mask / bands".into(),
            got: format!("mask {rows}×{w}, {bands} bands"),
            expected: "a non-empty mask and at least one band".into(),
        });
    }
    if y.shape() != (rows, wy) {
        return Err(NetError::Input {
            what: "measurement".into(),
            got: format!("{}×{}", y.rows(), y.cols()),
            expected: format!(
                "{rows}×{wy} (mask {rows}×{w} + {step}·({bands}−1) dispersed columns)"
            ),
        });
    }
    let scale_div = bands as f32;
    let ys: Vec<f32> = y.as_slice().iter().map(|v| (v / scale_div) * 2.0).collect();
    let mut h = vec![0.0f32; bands * rows * w];
    let mut phi = vec![0.0f32; bands * rows * wy];
    for c in 0..bands {
        for r in 0..rows {
            h[(c * rows + r) * w..][..w].copy_from_slice(&ys[r * wy + step * c..][..w]);
            phi[(c * rows + r) * wy + step * c..][..w].copy_from_slice(mask.row(r));
        }
    }
    Ok((
        Tensor::new(vec![1, bands, rows, w], h)?,
        Tensor::new(vec![1, bands, rows, wy], phi)?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_pixel_lands_where_the_toolbox_puts_it() {
        // 2 bands, step 2, mask 1×3 → measurement 1×5.
        let mask = Mask::from_vec(1, 3, vec![0.5, 1.0, 0.25]).unwrap();
        let y = Measurement::from_vec(1, 5, vec![0.0, 0.0, 4.0, 0.0, 0.0]).unwrap();
        let (h, phi) = toolbox_inputs(&y, &mask, 2, 2).unwrap();
        assert_eq!(h.shape(), [1, 2, 1, 3]);
        // ys = y / 2 · 2 = y; band 0 reads cols 0..3, band 1 cols 2..5.
        assert_eq!(h.data(), [0.0, 0.0, 4.0, 4.0, 0.0, 0.0]);
        assert_eq!(phi.shape(), [1, 2, 1, 5]);
        assert_eq!(
            phi.data(),
            [0.5, 1.0, 0.25, 0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.25]
        );
        let wrong = Measurement::from_vec(1, 4, vec![0.0; 4]).unwrap();
        let e = toolbox_inputs(&wrong, &mask, 2, 2).unwrap_err().to_string();
        assert!(e.contains("1×4") && e.contains("1×5"), "{e}");
    }

    /// A calibrated pose changes Phi by exactly the warp of the mask, band
    /// by band at the trained step, and nothing else; H does not change.
    #[test]
    fn a_calibrated_pose_warps_phi_and_only_phi() {
        let (rows, w, bands, step) = (12, 10, 3, 2);
        let mask = Mask::from_vec(
            rows,
            w,
            (0..rows * w)
                .map(|i| ((i * 7 + i / 5) % 3) as f32 / 2.0)
                .collect(),
        )
        .unwrap();
        let wy = w + step * (bands - 1);
        let y =
            Measurement::from_vec(rows, wy, (0..rows * wy).map(|i| i as f32).collect()).unwrap();
        let pose = MaskPose {
            dx: 1.25,
            dy: -0.5,
            theta_deg: 2.0,
        };
        let nominal = posed_inputs(&y, &mask, &MaskPose::default(), bands, step).unwrap();
        let posed = posed_inputs(&y, &mask, &pose, bands, step).unwrap();
        assert_eq!(posed.width_fitted, None);
        assert_eq!(posed.h.data(), nominal.h.data());
        assert_eq!(
            nominal.phi.data(),
            toolbox_inputs(&y, &mask, bands, step).unwrap().1.data()
        );
        let warped = warp_mask(&mask, &pose);
        assert_ne!(warped, mask);
        let phi = posed.phi.data();
        for c in 0..bands {
            for r in 0..rows {
                for j in 0..wy {
                    let want = if (step * c..step * c + w).contains(&j) {
                        warped.get(r, j - step * c)
                    } else {
                        0.0
                    };
                    assert_eq!(phi[(c * rows + r) * wy + j], want, "band {c} ({r}, {j})");
                }
            }
        }
    }

    /// A measurement a column wider (a1 slightly above 2) is cropped on the
    /// right and says so; one with other rows is refused with both shapes.
    #[test]
    fn measurement_width_is_fitted_and_rows_checked() {
        let mask = Mask::from_vec(2, 3, vec![1.0; 6]).unwrap();
        let y = Measurement::from_vec(2, 6, (0..12).map(|i| i as f32).collect()).unwrap();
        let p = posed_inputs(&y, &mask, &MaskPose::default(), 2, 2).unwrap();
        assert_eq!(p.width_fitted, Some((6, 5)));
        // band 1 reads columns 2..5 of each row: y / 2 · 2 = y
        assert_eq!(&p.h.data()[6..9], [2.0, 3.0, 4.0]);
        let bad = Measurement::from_vec(3, 5, vec![0.0; 15]).unwrap();
        let e = posed_inputs(&bad, &mask, &MaskPose::default(), 2, 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("3×5") && e.contains("2 rows"), "{e}");
        let nan = MaskPose {
            dx: f64::NAN,
            ..MaskPose::default()
        };
        assert!(posed_inputs(&y, &mask, &nan, 2, 2).is_err());
    }
}
