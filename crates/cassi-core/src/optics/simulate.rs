//! A CASSI snapshot of a scene through the true (mismatched) instrument.

use serde::{Deserialize, Serialize};

use super::dispersion::DispersionModel;
use super::noise::NoiseModel;
use super::operator::CassiOperator;
use crate::cube::{Cube, Mask, Measurement};
use crate::error::{Result, shape_error};
use crate::params::Mismatch;

/// Everything besides the scene and the nominal mask that fixes a simulated
/// measurement; stored beside it so it can be reproduced.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimulationSpec {
    /// The true instrument relative to the nominal one.
    pub mismatch: Mismatch,
    pub model: DispersionModel,
    /// `None`: a noise-free measurement.
    pub noise: Option<NoiseModel>,
}

/// y = A_true x (+ noise). The scene must have the mask's rows and cols.
pub fn simulate(scene: &Cube, nominal_mask: &Mask, spec: &SimulationSpec) -> Result<Measurement> {
    if (scene.rows(), scene.cols()) != nominal_mask.shape() {
        return Err(shape_error(
            "scene (rows, cols)",
            format!("{}×{}", scene.rows(), scene.cols()),
            format!(
                "{}×{} (the mask's size)",
                nominal_mask.rows(),
                nominal_mask.cols()
            ),
        ));
    }
    scene.check_finite("scene")?;
    let op = CassiOperator::with_mismatch(nominal_mask, scene.bands(), &spec.mismatch, spec.model)?;
    let clean = op.forward(scene)?;
    match &spec.noise {
        Some(noise) => noise.apply(&clean),
        None => Ok(clean),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cube::Frame;

    #[test]
    fn paper_mismatch_widens_the_detector_by_one_column() {
        let scene = Cube::from_vec(28, 8, 8, vec![0.5; 28 * 64]).unwrap();
        let mask = Frame::from_vec(8, 8, vec![1.0; 64]).unwrap();
        let spec = SimulationSpec {
            mismatch: Mismatch::paper(),
            model: DispersionModel::Rounded,
            noise: None,
        };
        assert_eq!(simulate(&scene, &mask, &spec).unwrap().shape(), (8, 8 + 55));
        let e = simulate(&Cube::zeros(28, 8, 9), &mask, &spec)
            .unwrap_err()
            .to_string();
        assert!(e.contains("8×9") && e.contains("8×8"), "{e}");
        let mut bad = scene.clone();
        bad.set(3, 1, 2, f32::INFINITY);
        assert!(
            simulate(&bad, &mask, &spec)
                .unwrap_err()
                .to_string()
                .contains("band 3, row 1, col 2")
        );
    }
}
