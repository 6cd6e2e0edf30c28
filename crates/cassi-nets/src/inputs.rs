//! The network inputs of the MST toolbox (caiyuanhao1998/MST, its
//! `template.py` and `test.py`), built from a raw CASSI measurement and the
//! coded aperture: H (`input_setting 'H'`), the measurement scaled and
//! shifted back into a cube, and Phi (`input_mask 'Phi'`), the mask shifted
//! per band.

use cassi_core::{Mask, Measurement};

use crate::error::{NetError, Result};
use crate::tensor::Tensor;

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
}
