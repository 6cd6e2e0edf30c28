//! The forward model of a whole mismatch vector ψ: the CASSI operator of ψ's
//! mask pose and dispersion, followed by ψ's optical blur when σ > 0. Every
//! reconstruction and calibration builds its operator here, so a blur in ψ
//! (from a calibration file or a simulation's sidecar) can never be dropped
//! on the way to a solver.

use super::blur::Blurred;
use super::dispersion::DispersionModel;
use super::operator::CassiOperator;
use crate::cube::{Cube, Frame, Mask, Measurement};
use crate::error::{Result, shape_error};
use crate::linop::{AatNormaliser, LinearOperator, NonNegativeOperator};
use crate::params::Mismatch;

/// y = B(σ) A(ψ) x, or A(ψ) x for a sharp instrument (σ = 0).
pub enum ModelOperator {
    Sharp(CassiOperator),
    Blurred(Blurred<CassiOperator>),
}

impl ModelOperator {
    /// The instrument `nominal_mask` moved, dispersed and blurred as `psi`
    /// says, for cubes of `bands` bands.
    pub fn new(
        nominal_mask: &Mask,
        bands: usize,
        psi: &Mismatch,
        model: DispersionModel,
    ) -> Result<Self> {
        psi.validate()?;
        let sharp = CassiOperator::with_mismatch(nominal_mask, bands, &psi.sharp(), model)?;
        Self::from_sharp(sharp, psi.blur_sigma_px)
    }

    /// `sharp` followed by a blur of `sigma_px` (none when 0).
    pub fn from_sharp(sharp: CassiOperator, sigma_px: f64) -> Result<Self> {
        if sigma_px == 0.0 {
            return Ok(Self::Sharp(sharp));
        }
        let (rows, cols) = sharp.measurement_shape();
        Ok(Self::Blurred(Blurred::new(sharp, sigma_px, rows, cols)?))
    }

    /// The CASSI operator before the blur.
    pub fn cassi(&self) -> &CassiOperator {
        match self {
            Self::Sharp(a) => a,
            Self::Blurred(b) => b.inner(),
        }
    }

    /// The CASSI operator when there is no blur.
    pub fn sharp(&self) -> Option<&CassiOperator> {
        match self {
            Self::Sharp(a) => Some(a),
            Self::Blurred(_) => None,
        }
    }

    /// The blur after the CASSI operator (`None` for a sharp instrument).
    pub fn blur(&self) -> Option<&super::blur::GaussianBlur> {
        match self {
            Self::Sharp(_) => None,
            Self::Blurred(b) => Some(b.blur()),
        }
    }

    /// σ of the blur, pixels (0 for a sharp instrument).
    pub fn blur_sigma_px(&self) -> f64 {
        match self {
            Self::Sharp(_) => 0.0,
            Self::Blurred(b) => b.blur().sigma(),
        }
    }

    /// (bands, rows, cols) of the cubes it takes.
    pub fn cube_shape(&self) -> (usize, usize, usize) {
        self.cassi().cube_shape()
    }

    /// (rows, detector cols) of the measurements it makes.
    pub fn measurement_shape(&self) -> (usize, usize) {
        self.cassi().measurement_shape()
    }

    /// y = B A x for a cube of [`Self::cube_shape`].
    pub fn forward(&self, cube: &Cube) -> Result<Measurement> {
        match self {
            Self::Sharp(a) => a.forward(cube),
            Self::Blurred(_) => {
                if cube.shape() != self.cube_shape() {
                    let (l, h, w) = self.cube_shape();
                    let (cl, ch, cw) = cube.shape();
                    return Err(shape_error(
                        "scene cube (bands, rows, cols)",
                        format!("({cl}, {ch}, {cw})"),
                        format!("({l}, {h}, {w}) to match the {h}×{w} mask and {l} bands"),
                    ));
                }
                let (rows, cols) = self.measurement_shape();
                let mut y = Frame::zeros(rows, cols);
                self.apply(cube.as_slice(), y.as_mut_slice());
                Ok(y)
            }
        }
    }

    fn linear(&self) -> &dyn LinearOperator {
        match self {
            Self::Sharp(a) => a,
            Self::Blurred(b) => b,
        }
    }
}

impl NonNegativeOperator for ModelOperator {}

impl LinearOperator for ModelOperator {
    fn domain_len(&self) -> usize {
        self.linear().domain_len()
    }
    fn range_len(&self) -> usize {
        self.linear().range_len()
    }
    fn apply(&self, x: &[f32], y: &mut [f32]) {
        self.linear().apply(x, y)
    }
    fn adjoint(&self, y: &[f32], x: &mut [f32]) {
        self.linear().adjoint(y, x)
    }
    fn diag_aat(&self) -> Option<Vec<f32>> {
        self.linear().diag_aat()
    }
    fn aat_normaliser(&self) -> Option<AatNormaliser> {
        self.linear().aat_normaliser()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linop::adjoint_mismatch;
    use crate::synth::random_binary_mask;

    #[test]
    fn the_blur_in_psi_reaches_the_operator_and_zero_means_sharp() {
        let mask = random_binary_mask(12, 14, 0.5, 3).unwrap();
        let psi = Mismatch {
            blur_sigma_px: 0.6,
            ..Mismatch::paper()
        };
        for model in DispersionModel::ALL {
            let blurred = ModelOperator::new(&mask, 4, &psi, model).unwrap();
            assert_eq!(blurred.blur_sigma_px(), 0.6);
            assert!(adjoint_mismatch(&blurred, 1) < 1e-5);
            let sharp = ModelOperator::new(&mask, 4, &psi.sharp(), model).unwrap();
            assert!(matches!(sharp, ModelOperator::Sharp(_)));
            let mut x = Cube::zeros(4, 12, 14);
            for (i, v) in x.as_mut_slice().iter_mut().enumerate() {
                *v = (i % 5) as f32 / 4.0;
            }
            let (yb, ys) = (blurred.forward(&x).unwrap(), sharp.forward(&x).unwrap());
            let diff: f32 = yb
                .as_slice()
                .iter()
                .zip(ys.as_slice())
                .map(|(a, b)| (a - b).abs())
                .sum();
            assert!(diff > 1.0, "the blur changed nothing: {diff}");
            assert!(blurred.forward(&Cube::zeros(3, 12, 14)).is_err());
        }
    }
}
