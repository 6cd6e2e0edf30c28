//! The forward model of a whole mismatch vector ψ: the CASSI operator of ψ's
//! mask pose and dispersion, followed by ψ's optical blur when σ > 0. Every
//! reconstruction and calibration builds its operator here, so a blur in ψ
//! (from a calibration file or a simulation's sidecar) can never be dropped
//! on the way to a solver.

use super::band_spread::BandSpread;
use super::blur::{Blurred, GaussianBlur};
use super::crisp_cells::CrispCellOperator;
use super::dispersion::{Dispersion, DispersionModel};
use super::operator::{CassiOperator, CubeRows, checked_forward};
use crate::cube::{Cube, Mask, Measurement};
use crate::error::Result;
use crate::linop::{AatNormaliser, LinearOperator, NonNegativeOperator};
use crate::params::Mismatch;
use crate::simd::Simd;

thread_local! {
    /// The crisp-cell model's Aᵀ y, read row by row.
    static ADJOINT_CUBE: std::cell::RefCell<Vec<f32>> = std::cell::RefCell::default();
}

/// y = B(σ) A(ψ) x, or A(ψ) x for a sharp instrument (σ = 0), or the
/// crisp-cell model's operator (its blur inside; sharp, it is the
/// dispersed-mask model's taps).
pub enum ModelOperator {
    Sharp(CassiOperator),
    Blurred(Blurred<CassiOperator>),
    Cells(CrispCellOperator),
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
        let model = match model {
            // sharp, the crisp-cell model is the dispersed-mask model
            // (tested), whose taps are faster
            DispersionModel::CrispCells if psi.blur_sigma_px == 0.0 => {
                DispersionModel::DispersedMask
            }
            DispersionModel::CrispCells => {
                return Ok(Self::Cells(CrispCellOperator::new(
                    nominal_mask,
                    bands,
                    psi,
                )?));
            }
            other => other,
        };
        let sharp = CassiOperator::with_mismatch(nominal_mask, bands, &psi.sharp(), model)?;
        Self::from_sharp(sharp, psi.blur_sigma_px)
    }

    /// `psi`'s instrument with band k landing `along[k]` px further along
    /// the dispersion than a1·k + a2·k² ([`Dispersion::shifted_along`]).
    pub fn with_band_shifts(
        nominal_mask: &Mask,
        bands: usize,
        psi: &Mismatch,
        model: DispersionModel,
        along: &[f64],
    ) -> Result<Self> {
        psi.validate()?;
        let (taps, cells) = match model {
            // the crisp-cell model lands its cells where the dispersed-mask
            // model's taps put the bands (sharp, it is that model)
            DispersionModel::CrispCells => {
                (DispersionModel::DispersedMask, psi.blur_sigma_px != 0.0)
            }
            other => (other, false),
        };
        let dispersion = Dispersion::new(bands, psi.dispersion(), taps)?.shifted_along(along)?;
        if cells {
            return Ok(Self::Cells(CrispCellOperator::dispersed(
                nominal_mask,
                psi,
                dispersion,
            )?));
        }
        let sharp = CassiOperator::posed(nominal_mask, psi.pose(), dispersion)?;
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

    /// This operator with each band's light spread along the dispersion
    /// as `spread` says, bands `spacing_px` apart: a row kernel in the blur
    /// (a sharp instrument gets a blur of σ 0 for it; a point changes
    /// nothing).
    pub fn with_band_spread(self, spread: BandSpread, spacing_px: f64) -> Result<Self> {
        if spread == BandSpread::Point {
            return Ok(self);
        }
        Ok(match self {
            Self::Sharp(a) => {
                let (rows, cols) = a.measurement_shape();
                let blur = GaussianBlur::with_band_spread(0.0, spread, spacing_px, rows, cols)?;
                Self::Blurred(Blurred::with_blur(a, blur)?)
            }
            Self::Blurred(b) => {
                let blur = b.blur().with_spread(spread, spacing_px)?;
                Self::Blurred(Blurred::with_blur(b.into_inner(), blur)?)
            }
            Self::Cells(c) => Self::Cells(c.with_band_spread(spread, spacing_px)?),
        })
    }

    /// The tapped CASSI operator before any blur (`None` for the
    /// crisp-cell model, which blurs each cell where it lands).
    pub fn cassi(&self) -> Option<&CassiOperator> {
        match self {
            Self::Sharp(a) => Some(a),
            Self::Blurred(b) => Some(b.inner()),
            Self::Cells(_) => None,
        }
    }

    /// The CASSI operator when there is no blur.
    pub fn sharp(&self) -> Option<&CassiOperator> {
        match self {
            Self::Sharp(a) => Some(a),
            Self::Blurred(_) | Self::Cells(_) => None,
        }
    }

    /// The blur after the tapped CASSI operator (`None` for a sharp
    /// instrument and for the crisp-cell model).
    pub fn blur(&self) -> Option<&super::blur::GaussianBlur> {
        match self {
            Self::Sharp(_) | Self::Cells(_) => None,
            Self::Blurred(b) => Some(b.blur()),
        }
    }

    /// σ of the blur, pixels (0 for a sharp instrument).
    pub fn blur_sigma_px(&self) -> f64 {
        match self {
            Self::Sharp(_) => 0.0,
            Self::Blurred(b) => b.blur().sigma(),
            Self::Cells(c) => c.blur_sigma_px(),
        }
    }

    /// (bands, rows, cols) of the cubes it takes.
    pub fn cube_shape(&self) -> (usize, usize, usize) {
        match self {
            Self::Sharp(a) => a.cube_shape(),
            Self::Blurred(b) => b.inner().cube_shape(),
            Self::Cells(c) => c.cube_shape(),
        }
    }

    /// (rows, detector cols) of the measurements it makes.
    pub fn measurement_shape(&self) -> (usize, usize) {
        match self {
            Self::Sharp(a) => a.measurement_shape(),
            Self::Blurred(b) => b.inner().measurement_shape(),
            Self::Cells(c) => c.measurement_shape(),
        }
    }

    /// y = B A x for a cube of [`Self::cube_shape`].
    pub fn forward(&self, cube: &Cube) -> Result<Measurement> {
        checked_forward(self, self.cube_shape(), self.measurement_shape(), cube)
    }

    /// y = A x for a cube given row by row (the scene fit's coarse scene,
    /// never stored by the tapped models).
    pub(crate) fn apply_rows<R: CubeRows>(&self, x: &R, y: &mut [f32]) {
        match self {
            Self::Sharp(a) => a.apply_rows(x, y),
            Self::Blurred(b) => b.apply_after(|ax| b.inner().apply_rows(x, ax), y),
            Self::Cells(c) => c.apply_rows(x, y),
        }
    }

    /// Runs `f` with the rows of Aᵀ y: `f` gets a function that writes row
    /// `r` of band `k` into its buffer (for the scene fit, which sums
    /// them into its coarse scene as they come).
    pub(crate) fn with_adjoint_rows<T>(
        &self,
        y: &[f32],
        f: impl FnOnce(&(dyn Fn(usize, usize, &mut [f32]) + Sync)) -> T,
    ) -> T {
        let simd = Simd::detect(false);
        match self {
            Self::Sharp(a) => f(&|k, r, row| a.adjoint_row(simd, y, k, r, row)),
            Self::Blurred(b) => b.adjoint_before(y, |by| {
                f(&|k, r, row| b.inner().adjoint_row(simd, by, k, r, row))
            }),
            Self::Cells(c) => crate::scratch::with_taken(&ADJOINT_CUBE, |x| {
                let (_, rows, cols) = c.cube_shape();
                x.resize(c.domain_len(), 0.0);
                c.adjoint(y, x);
                f(&|k, r, row| row.copy_from_slice(&x[(k * rows + r) * cols..][..cols]))
            }),
        }
    }

    fn linear(&self) -> &dyn LinearOperator {
        match self {
            Self::Sharp(a) => a,
            Self::Blurred(b) => b,
            Self::Cells(c) => c,
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

    /// Band shifts: the adjoint holds, no shift is the plain operator, and
    /// a shifted band moves its own light alone.
    #[test]
    fn a_shifted_band_moves_its_own_light_alone() {
        let mask = random_binary_mask(12, 14, 0.5, 3).unwrap();
        let psi = Mismatch {
            blur_sigma_px: 0.6,
            ..Mismatch::paper()
        };
        let one_band = |k: usize| {
            let mut x = Cube::zeros(4, 12, 14);
            x.band_mut(k)
                .iter_mut()
                .enumerate()
                .for_each(|(i, v)| *v = (i % 7) as f32);
            x
        };
        // the crisp-cell model too: it lands its cells where the shifted
        // taps put the bands
        for model in DispersionModel::ALL {
            let plain = ModelOperator::new(&mask, 4, &psi, model).unwrap();
            let unshifted =
                ModelOperator::with_band_shifts(&mask, 4, &psi, model, &[0.0; 4]).unwrap();
            let shifted =
                ModelOperator::with_band_shifts(&mask, 4, &psi, model, &[0.0, 0.0, 0.7, 0.0])
                    .unwrap();
            assert!(adjoint_mismatch(&shifted, 2) < 1e-5, "{model:?}");
            for k in 0..4 {
                let x = one_band(k);
                let y = |op: &ModelOperator| op.forward(&x).unwrap().as_slice().to_vec();
                assert_eq!(y(&plain), y(&unshifted), "{model:?} band {k}");
                let moved = y(&plain) != y(&shifted);
                assert_eq!(moved, k == 2, "{model:?} band {k}");
            }
        }
    }
}
