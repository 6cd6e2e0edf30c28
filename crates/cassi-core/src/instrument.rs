//! The instrument's fixed description: band count, nominal dispersion stride
//! and the band-centre wavelengths.

use serde::{Deserialize, Serialize};

use crate::error::{CassiError, Result};
use crate::params::{MAX_SLOPE, MIN_SLOPE};

/// The 28 band centres (nm) of the standard KAIST/TSA CASSI benchmark.
pub const STANDARD_WAVELENGTHS_NM: [f64; 28] = [
    453.3, 457.6, 462.1, 466.8, 471.6, 476.5, 481.6, 486.9, 492.4, 498.0, 503.9, 509.9, 516.2,
    522.7, 529.5, 536.5, 543.8, 551.4, 559.3, 567.5, 575.9, 584.8, 594.4, 604.2, 614.4, 625.1,
    636.3, 648.1,
];

/// Nominal CASSI design: `bands` spectral bands (band 0 shortest wavelength)
/// dispersed `stride` detector columns apart.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Instrument {
    pub bands: usize,
    /// Nominal dispersion in detector pixels per band (the nominal a1).
    pub stride: f64,
    /// Band-centre wavelengths in nm, increasing, one per band.
    pub wavelengths_nm: Vec<f64>,
}

impl Default for Instrument {
    /// The standard benchmark: 28 bands, stride 2.
    fn default() -> Self {
        Self {
            bands: 28,
            stride: 2.0,
            wavelengths_nm: STANDARD_WAVELENGTHS_NM.to_vec(),
        }
    }
}

impl Instrument {
    /// `bands` bands with wavelengths spread evenly over the standard range
    /// (the standard 28 exactly when `bands == 28`).
    pub fn with_bands(bands: usize, stride: f64) -> Result<Self> {
        let wavelengths_nm = if bands == 28 {
            STANDARD_WAVELENGTHS_NM.to_vec()
        } else {
            let (lo, hi) = (STANDARD_WAVELENGTHS_NM[0], STANDARD_WAVELENGTHS_NM[27]);
            (0..bands)
                .map(|k| {
                    if bands == 1 {
                        0.5 * (lo + hi)
                    } else {
                        lo + (hi - lo) * k as f64 / (bands - 1) as f64
                    }
                })
                .collect()
        };
        let inst = Self {
            bands,
            stride,
            wavelengths_nm,
        };
        inst.validate()?;
        Ok(inst)
    }

    pub fn validate(&self) -> Result<()> {
        if self.bands == 0 {
            return Err(CassiError::InvalidParameter {
                name: "bands",
                value: 0.0,
                reason: "an instrument needs at least one band".into(),
            });
        }
        if !(MIN_SLOPE < self.stride && self.stride < MAX_SLOPE) {
            return Err(CassiError::InvalidParameter {
                name: "stride",
                value: self.stride,
                reason: format!(
                    "the nominal dispersion must lie between {MIN_SLOPE} and {MAX_SLOPE} \
                     pixels per band"
                ),
            });
        }
        if self.wavelengths_nm.len() != self.bands {
            return Err(CassiError::Shape {
                what: "wavelengths_nm".into(),
                got: format!("{} values", self.wavelengths_nm.len()),
                expected: format!("{} values (one per band)", self.bands),
            });
        }
        if self.wavelengths_nm.windows(2).any(|w| w[1] <= w[0])
            || self.wavelengths_nm.iter().any(|w| !w.is_finite())
        {
            return Err(CassiError::InvalidParameter {
                name: "wavelengths_nm",
                value: f64::NAN,
                reason:
                    "wavelengths must be finite and strictly increasing (band 0 is the shortest)"
                        .into(),
            });
        }
        Ok(())
    }
}
