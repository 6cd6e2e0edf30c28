//! The assumed instrument a reconstruction inverts: the nominal mask, the
//! cube's bands, the nominal stride, the mismatch ψ it is moved, dispersed
//! and blurred by (nominal, calibrated or true), the dispersion model and,
//! where known, each band's fixed departure from the straight dispersion
//! and how each band's light spreads along it.
//! One value, checked once, so every reconstruction entry point takes the
//! same thing and none can drop a part of it (the blur, say) on the way.

use crate::cube::Mask;
use crate::error::{CassiError, Result};
use crate::optics::{BandOffsets, BandSpread, DispersionModel, ModelOperator, validate_mask};
use crate::params::Mismatch;

/// The instrument a reconstruction assumes. Build it with [`Model::new`],
/// which is where it is validated.
#[derive(Debug, Clone, Copy)]
pub struct Model<'m> {
    nominal_mask: &'m Mask,
    bands: usize,
    stride: f64,
    mismatch: Mismatch,
    dispersion: DispersionModel,
    band_offsets: Option<&'m BandOffsets>,
    band_spread: BandSpread,
}

impl<'m> Model<'m> {
    /// `nominal_mask` moved, dispersed and blurred as `mismatch` says, for
    /// cubes of `bands` bands; `stride` is the nominal dispersion (px per
    /// band) the instrument was designed for, which networks are trained on.
    pub fn new(
        nominal_mask: &'m Mask,
        bands: usize,
        stride: f64,
        mismatch: Mismatch,
        dispersion: DispersionModel,
    ) -> Result<Self> {
        mismatch.validate()?;
        validate_mask(nominal_mask, "nominal mask")?;
        if bands == 0 {
            return Err(CassiError::InvalidParameter {
                name: "bands",
                value: 0.0,
                reason: "a cube has at least one band".into(),
            });
        }
        if !(stride.is_finite() && stride > 0.0) {
            return Err(CassiError::InvalidParameter {
                name: "stride",
                value: stride,
                reason: "the nominal stride is a finite number of pixels per band > 0".into(),
            });
        }
        Ok(Self {
            nominal_mask,
            bands,
            stride,
            mismatch,
            dispersion,
            band_offsets: None,
            band_spread: BandSpread::Point,
        })
    }

    /// The nominal instrument: no mismatch, dispersion `stride` px per band.
    pub fn nominal(
        nominal_mask: &'m Mask,
        bands: usize,
        stride: f64,
        dispersion: DispersionModel,
    ) -> Result<Self> {
        Self::new(
            nominal_mask,
            bands,
            stride,
            Mismatch::nominal(stride),
            dispersion,
        )
    }

    /// This instrument with another mismatch (a scenario's, a calibration's).
    pub fn with_mismatch(&self, mismatch: Mismatch) -> Result<Self> {
        mismatch.validate()?;
        Ok(Self { mismatch, ..*self })
    }

    /// This instrument with `nominal_mask` in place of its own (a band of
    /// its rows, say); bands, stride, mismatch, family and band offsets
    /// kept.
    pub fn with_mask<'n>(&self, nominal_mask: &'n Mask) -> Result<Model<'n>>
    where
        'm: 'n,
    {
        let model = Model::new(
            nominal_mask,
            self.bands,
            self.stride,
            self.mismatch,
            self.dispersion,
        )?;
        Ok(Model {
            band_offsets: self.band_offsets,
            band_spread: self.band_spread,
            ..model
        })
    }

    /// This instrument with its bands `offsets` off the straight
    /// dispersion ([`BandOffsets`]), held whatever ψ says.
    pub fn with_band_offsets(&self, offsets: &'m BandOffsets) -> Result<Self> {
        offsets.check(self.bands)?;
        Ok(Self {
            band_offsets: Some(offsets),
            ..*self
        })
    }

    /// This instrument with each band's light spread along the dispersion
    /// as `spread` says ([`BandSpread`]; over ψ's a1, the bands' spacing).
    pub fn with_band_spread(&self, spread: BandSpread) -> Self {
        Self {
            band_spread: spread,
            ..*self
        }
    }

    /// This instrument holding what a calibration held beside ψ: its band
    /// offsets (if any) and its band spread.
    pub fn holding(&self, offsets: Option<&'m BandOffsets>, spread: BandSpread) -> Result<Self> {
        let held = match offsets {
            Some(o) => self.with_band_offsets(o)?,
            None => *self,
        };
        Ok(held.with_band_spread(spread))
    }

    /// This instrument fitted with another dispersion family (nothing the
    /// constructor checks depends on it).
    pub fn with_dispersion(&self, dispersion: DispersionModel) -> Self {
        Self {
            dispersion,
            ..*self
        }
    }

    pub fn nominal_mask(&self) -> &'m Mask {
        self.nominal_mask
    }

    pub fn bands(&self) -> usize {
        self.bands
    }

    /// Nominal dispersion, detector columns per band.
    pub fn stride(&self) -> f64 {
        self.stride
    }

    /// ψ: mask pose, dispersion and blur σ.
    pub fn mismatch(&self) -> &Mismatch {
        &self.mismatch
    }

    pub fn dispersion(&self) -> DispersionModel {
        self.dispersion
    }

    /// Where each band's light lies along the dispersion.
    pub fn band_spread(&self) -> BandSpread {
        self.band_spread
    }

    /// The bands' fixed departures from the straight dispersion, if held.
    pub fn band_offsets(&self) -> Option<&'m BandOffsets> {
        self.band_offsets
    }

    /// B(σ)·A(ψ): the forward operator of this instrument.
    pub fn operator(&self) -> Result<ModelOperator> {
        self.operator_at(&self.mismatch)
    }

    /// The forward operator of this instrument moved, dispersed and blurred
    /// as `psi` says (a calibration's candidate), its band offsets held.
    pub fn operator_at(&self, psi: &Mismatch) -> Result<ModelOperator> {
        let op = match self.band_offsets {
            None => ModelOperator::new(self.nominal_mask, self.bands, psi, self.dispersion),
            Some(o) => ModelOperator::with_band_shifts(
                self.nominal_mask,
                self.bands,
                psi,
                self.dispersion,
                o.as_slice(),
            ),
        }?;
        op.with_band_spread(self.band_spread, psi.a1)
    }

    /// [`Self::operator_at`] with band k moved a further `along[k]` px
    /// along the dispersion, on top of any offsets held (a band-shift
    /// fit's candidate); the band spread held too.
    pub fn operator_shifted(&self, psi: &Mismatch, along: &[f64]) -> Result<ModelOperator> {
        let total: Vec<f64> = match self.band_offsets {
            Some(held) => along
                .iter()
                .zip(held.as_slice())
                .map(|(a, h)| a + h)
                .collect(),
            None => along.to_vec(),
        };
        ModelOperator::with_band_shifts(
            self.nominal_mask,
            self.bands,
            psi,
            self.dispersion,
            &total,
        )?
        .with_band_spread(self.band_spread, psi.a1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_instruments_are_refused_where_they_are_built() {
        let mask = Mask::from_vec(4, 4, vec![1.0; 16]).unwrap();
        let ok = Model::nominal(&mask, 3, 2.0, DispersionModel::Rounded).unwrap();
        assert_eq!(ok.operator().unwrap().cube_shape(), (3, 4, 4));
        assert_eq!(ok.mismatch(), &Mismatch::nominal(2.0));
        let bad_blur = Mismatch {
            blur_sigma_px: -1.0,
            ..Mismatch::nominal(2.0)
        };
        assert!(
            ok.with_mismatch(bad_blur)
                .unwrap_err()
                .to_string()
                .contains("blur_sigma_px")
        );
        let e = Model::nominal(&mask, 0, 2.0, DispersionModel::Rounded).unwrap_err();
        assert!(e.to_string().contains("bands"), "{e}");
        let e = Model::new(
            &mask,
            3,
            f64::NAN,
            Mismatch::nominal(2.0),
            DispersionModel::Rounded,
        )
        .unwrap_err();
        assert!(e.to_string().contains("stride"), "{e}");
        // band offsets: held by its operators, their count checked
        let offsets = BandOffsets::from_table(&[0.0, 1.4, 0.4], 2.0).unwrap();
        let held = ok.with_band_offsets(&offsets).unwrap();
        let psi = Mismatch {
            dx: 0.3,
            ..Mismatch::nominal(2.0)
        };
        let shifted = ModelOperator::with_band_shifts(
            &mask,
            3,
            &psi,
            DispersionModel::Rounded,
            offsets.as_slice(),
        )
        .unwrap();
        let x = crate::cube::Cube::from_vec(3, 4, 4, (0..48).map(|v| v as f32).collect()).unwrap();
        let y = |op: ModelOperator| op.forward(&x).unwrap().as_slice().to_vec();
        assert_eq!(y(held.operator_at(&psi).unwrap()), y(shifted));
        assert_eq!(
            y(held.with_mismatch(psi).unwrap().operator().unwrap()),
            y(ModelOperator::with_band_shifts(
                &mask,
                3,
                &psi,
                DispersionModel::Rounded,
                offsets.as_slice()
            )
            .unwrap())
        );
        assert_ne!(
            y(held.operator_at(&psi).unwrap()),
            y(ok.operator_at(&psi).unwrap())
        );
        let four = BandOffsets::from_table(&[0.0, 0.6, 0.2, 0.1], 2.0).unwrap();
        let e = ok.with_band_offsets(&four).unwrap_err().to_string();
        assert!(
            e.contains("band offsets") && e.contains("3 (one per band"),
            "{e}"
        );
        let bad_mask = Mask::from_vec(4, 4, vec![2.0; 16]).unwrap();
        assert!(Model::nominal(&bad_mask, 3, 2.0, DispersionModel::Rounded).is_err());
    }
}
