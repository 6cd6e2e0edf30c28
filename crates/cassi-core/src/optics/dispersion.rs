//! The prism: where each band lands on the detector.
//!
//! Band k is displaced by `d_k = a1·k + a2·k²` pixels along the dispersion
//! axis: `d_k·cos α` columns (toward larger column index) and `d_k·sin α`
//! rows. Two models of the true instrument:
//! - `Rounded`: both offsets rounded to integers, round-half-to-even (the
//!   paper's simulation); a1 and α act only through the rounding pattern.
//! - `Subpixel`: each band's light is split bilinearly between the
//!   neighbouring detector pixels, so fractional a1 and α act physically.
//! - `DispersedMask`: the same split of the scene, but the mask is sampled
//!   once where each band lands — the crisp mask moved by the pose and the
//!   band's own sub-pixel offset — instead of being sampled on the mask
//!   grid and then split again with the band (`Subpixel` interpolates the
//!   mask twice, which blurs its code by an amount that changes with the
//!   band's fractional offset). A camera integrates the dispersed crisp
//!   mask once per detector pixel; against the 4× oversampled simulator
//!   this model's residual at the true ψ is 1.4–1.9 % instead of 1.9–4.0 %
//!   (six tuning cases) and its scene-known fits land closer to the truth.
//!
//! Each band is described by a few [`Tap`]s (integer offset + weight); the
//! operator only ever sees taps, so both models share one code path.

use serde::{Deserialize, Serialize};

use crate::error::{CassiError, Result};
use crate::params::DispersionParams;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum DispersionModel {
    /// Integer offsets, round-half-to-even (the paper's simulation).
    #[default]
    Rounded,
    /// Linear interpolation between neighbouring detector pixels.
    Subpixel,
    /// `Subpixel` with the mask sampled where each band lands (one
    /// interpolation of the mask per band): the model for real cameras.
    #[serde(rename = "dispersed-mask")]
    DispersedMask,
    /// `DispersedMask` with each mask cell a crisp square blurred at its
    /// own sub-pixel landing offset
    /// ([`CrispCellOperator`](super::CrispCellOperator)): a blurred
    /// instrument's code between detector rows as a camera makes it.
    #[serde(rename = "crisp-cells")]
    CrispCells,
}

impl DispersionModel {
    /// Whether a measurement made through this model can tell parameter `p`
    /// at all: with rounded offsets a sub-degree tilt α moves no band by a
    /// whole row, so α leaves no trace.
    pub fn identifies(self, p: crate::params::Parameter) -> bool {
        !(self == Self::Rounded && p == crate::params::Parameter::AlphaDeg)
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Rounded => "rounded",
            Self::Subpixel => "subpixel",
            Self::DispersedMask => "dispersed-mask",
            Self::CrispCells => "crisp-cells",
        }
    }

    /// Every model, in the order the command line lists them.
    pub const ALL: [DispersionModel; 4] = [
        Self::Rounded,
        Self::Subpixel,
        Self::DispersedMask,
        Self::CrispCells,
    ];

    /// The models a [`CassiOperator`](super::CassiOperator) represents (a
    /// few taps per band); the crisp-cell model has its own operator.
    pub const TAPPED: [DispersionModel; 3] = [Self::Rounded, Self::Subpixel, Self::DispersedMask];

    /// Whether fractional offsets act (everything but `Rounded`): a1 and α
    /// are then continuous parameters.
    pub fn is_subpixel(self) -> bool {
        self != Self::Rounded
    }

    /// Whether the mask is sampled per band where that band lands.
    pub fn samples_mask_per_band(self) -> bool {
        matches!(self, Self::DispersedMask | Self::CrispCells)
    }

    /// Whether each crisp mask cell is blurred at its own landing offset
    /// (its operator is a [`CrispCellOperator`](super::CrispCellOperator),
    /// not taps).
    pub fn places_cells(self) -> bool {
        self == Self::CrispCells
    }
}

impl std::str::FromStr for DispersionModel {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "rounded" => Ok(Self::Rounded),
            "subpixel" => Ok(Self::Subpixel),
            "dispersed-mask" => Ok(Self::DispersedMask),
            "crisp-cells" => Ok(Self::CrispCells),
            other => Err(format!(
                "unknown dispersion model '{other}' (expected 'rounded', 'subpixel', 'dispersed-mask' or 'crisp-cells')"
            )),
        }
    }
}

/// One contribution of a band to the detector: light at mask pixel (r, c)
/// lands at detector pixel (r + row, c + col) with this weight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tap {
    pub row: i32,
    pub col: i32,
    pub weight: f32,
}

/// Per-band detector offsets for one (a1, α) and model.
#[derive(Debug, Clone, PartialEq)]
pub struct Dispersion {
    model: DispersionModel,
    params: DispersionParams,
    /// Continuous (col, row) offset of each band, before any rounding.
    offsets: Vec<(f64, f64)>,
    taps: Vec<Vec<Tap>>,
    extra_cols: usize,
}

/// Offsets larger than this many pixels are surely a unit mistake.
const MAX_OFFSET_PX: f64 = 100_000.0;

impl Dispersion {
    pub fn new(bands: usize, params: DispersionParams, model: DispersionModel) -> Result<Self> {
        params.validate()?;
        if bands == 0 {
            return Err(CassiError::InvalidParameter {
                name: "bands",
                value: 0.0,
                reason: "the dispersion needs at least one band".into(),
            });
        }
        // the bands land in order: the slope a1 + 2·a2·k, linear in k and
        // above the floor at k = 0 (validated), stays so at the last band —
        // else a band lands before band 0 and off the operator's columns
        let end_slope = params.a1 + 2.0 * params.a2 * (bands - 1) as f64;
        if end_slope < crate::params::MIN_SLOPE {
            return Err(CassiError::InvalidParameter {
                name: "a2",
                value: params.a2,
                reason: format!(
                    "with a1 = {} the dispersion would turn back before band {} (slope {end_slope:.4} \
                     px per band there): the bands must land in order",
                    params.a1,
                    bands - 1
                ),
            });
        }
        let alpha = params.alpha_deg.to_radians();
        let offsets: Vec<(f64, f64)> = (0..bands)
            .map(|k| {
                let along = params.along(k as f64);
                (along * alpha.cos(), along * alpha.sin())
            })
            .collect();
        Self::from_offsets(params, offsets, model)
    }

    /// A dispersion with explicit continuous (col, row) offsets per band
    /// (`params` is recorded, not used).
    pub(crate) fn from_offsets(
        params: DispersionParams,
        offsets: Vec<(f64, f64)>,
        model: DispersionModel,
    ) -> Result<Self> {
        let bands = offsets.len();
        let reach = offsets.last().map_or(0.0, |o| o.0.abs().max(o.1.abs()));
        if reach > MAX_OFFSET_PX {
            return Err(CassiError::InvalidParameter {
                name: "a1",
                value: params.a1,
                reason: format!(
                    "band {} would land {reach:.0} px away; a1 is in pixels per band",
                    bands - 1
                ),
            });
        }
        let taps: Vec<Vec<Tap>> = offsets
            .iter()
            .map(|&(dc, dr)| band_taps(dc, dr, model))
            .collect();
        let extra_cols = taps
            .iter()
            .flatten()
            .map(|t| t.col)
            .max()
            .unwrap_or(0)
            .max(0) as usize;
        Ok(Self {
            model,
            params,
            offsets,
            taps,
            extra_cols,
        })
    }

    /// The same dispersion with band k moved `along[k]` pixels further
    /// along its axis (direction α): band positions off the curve a1·k +
    /// a2·k², e.g. a prism whose dispersion no low-order polynomial follows.
    /// `along` must hold one shift per band, each finite; the bands must
    /// still land in order along the axis, band 0 at or after its start.
    pub fn shifted_along(&self, along: &[f64]) -> Result<Self> {
        let bands = self.bands();
        if along.len() != bands {
            return Err(crate::error::shape_error(
                "the band shifts",
                format!("{} values", along.len()),
                format!("{bands} (one per band)"),
            ));
        }
        if let Some((k, &v)) = along.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(CassiError::NonFinite {
                what: "the band shifts".into(),
                value: v as f32,
                location: format!("band {k}"),
            });
        }
        let alpha = self.params.alpha_deg.to_radians();
        let (c, r) = (alpha.cos(), alpha.sin());
        let position = |k: usize| self.params.along(k as f64) + along[k];
        // the operator's columns start where band 0 lands
        if position(0) < 0.0 {
            return Err(CassiError::InvalidParameter {
                name: "band shift",
                value: along[0],
                reason:
                    "band 0 would land before the mask's first column; shift the others instead"
                        .into(),
            });
        }
        if let Some(k) =
            (1..bands).find(|&k| position(k) - position(k - 1) < crate::params::MIN_SLOPE)
        {
            return Err(CassiError::InvalidParameter {
                name: "band shift",
                value: along[k],
                reason: format!(
                    "band {k} would land {:.3} px from band {} along the dispersion: the bands must land in order",
                    position(k) - position(k - 1),
                    k - 1
                ),
            });
        }
        let offsets = (0..bands)
            .map(|k| (position(k) * c, position(k) * r))
            .collect();
        Self::from_offsets(self.params, offsets, self.model)
    }

    /// The nominal design: integer stride, no tilt.
    pub fn nominal(bands: usize, stride: f64, model: DispersionModel) -> Result<Self> {
        Self::new(
            bands,
            DispersionParams {
                a1: stride,
                alpha_deg: 0.0,
                a2: 0.0,
            },
            model,
        )
    }

    pub fn model(&self) -> DispersionModel {
        self.model
    }
    pub fn params(&self) -> DispersionParams {
        self.params
    }
    pub fn bands(&self) -> usize {
        self.taps.len()
    }
    /// Continuous (col, row) offset of band k.
    pub fn offset(&self, k: usize) -> (f64, f64) {
        self.offsets[k]
    }
    pub fn taps(&self, k: usize) -> &[Tap] {
        &self.taps[k]
    }
    /// Detector columns beyond the mask width: W + this is the measurement
    /// width (max_k round(d_k) for `Rounded`, max_k ceil(d_k) for `Subpixel`).
    pub fn extra_cols(&self) -> usize {
        self.extra_cols
    }

    /// d(col, row offset of band k)/d a1.
    pub fn offset_rate_a1(&self, k: usize) -> (f64, f64) {
        let alpha = self.params.alpha_deg.to_radians();
        (k as f64 * alpha.cos(), k as f64 * alpha.sin())
    }

    /// d(col, row offset of band k)/d a2.
    pub fn offset_rate_a2(&self, k: usize) -> (f64, f64) {
        let alpha = self.params.alpha_deg.to_radians();
        let kk = (k * k) as f64;
        (kk * alpha.cos(), kk * alpha.sin())
    }

    /// d(col, row offset of band k)/d α, per degree.
    pub fn offset_rate_alpha_deg(&self, k: usize) -> (f64, f64) {
        let alpha = self.params.alpha_deg.to_radians();
        let along = self.params.along(k as f64);
        let s = along * std::f64::consts::PI / 180.0;
        (-s * alpha.sin(), s * alpha.cos())
    }

    /// `Subpixel` and `DispersedMask`: the derivative of every band's bilinear tap weights
    /// when band k's continuous offset moves at `rates[k]` = (d col, d row),
    /// at the four neighbouring pixels (a weight that is zero now may not
    /// stay zero). One-sided (to the right/below) where an offset sits on
    /// an integer, where the interpolant has a kink. Taps that would fall
    /// off this detector's columns are dropped: that light leaves the
    /// detector. `None` for `Rounded`, whose weights are piecewise constant.
    pub(crate) fn weight_derivatives(&self, rates: &[(f64, f64)]) -> Option<Dispersion> {
        if self.model == DispersionModel::Rounded {
            return None;
        }
        let taps = self
            .offsets
            .iter()
            .zip(rates)
            .map(|(&(dc, dr), &(rc, rr))| {
                let (c0, r0) = (dc.floor(), dr.floor());
                let (fc, fr) = (dc - c0, dr - r0);
                let (c0, r0) = (c0 as i32, r0 as i32);
                // d/dt of (1−fr)(1−fc), (1−fr)fc, fr(1−fc), fr·fc
                [
                    (r0, c0, -rr * (1.0 - fc) - rc * (1.0 - fr)),
                    (r0, c0 + 1, -rr * fc + rc * (1.0 - fr)),
                    (r0 + 1, c0, rr * (1.0 - fc) - rc * fr),
                    (r0 + 1, c0 + 1, rr * fc + rc * fr),
                ]
                .into_iter()
                .filter(|&(_, col, w)| w != 0.0 && col >= 0 && col as usize <= self.extra_cols)
                .map(|(row, col, w)| Tap {
                    row,
                    col,
                    weight: w as f32,
                })
                .collect()
            })
            .collect();
        Some(Dispersion {
            taps,
            ..self.clone()
        })
    }
}

fn band_taps(dc: f64, dr: f64, model: DispersionModel) -> Vec<Tap> {
    match model {
        DispersionModel::Rounded => vec![Tap {
            row: dr.round_ties_even() as i32,
            col: dc.round_ties_even() as i32,
            weight: 1.0,
        }],
        // the crisp-cell model's detector and offsets are the dispersed-mask
        // model's (its operator places cells itself)
        DispersionModel::Subpixel
        | DispersionModel::DispersedMask
        | DispersionModel::CrispCells => {
            let (c0, r0) = (dc.floor(), dr.floor());
            let (fc, fr) = (dc - c0, dr - r0);
            let (c0, r0) = (c0 as i32, r0 as i32);
            [
                (r0, c0, (1.0 - fr) * (1.0 - fc)),
                (r0, c0 + 1, (1.0 - fr) * fc),
                (r0 + 1, c0, fr * (1.0 - fc)),
                (r0 + 1, c0 + 1, fr * fc),
            ]
            .into_iter()
            .filter(|&(_, _, w)| w > 0.0)
            .map(|(row, col, w)| Tap {
                row,
                col,
                weight: w as f32,
            })
            .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_shifts_are_checked_and_no_shift_changes_nothing() {
        let params = DispersionParams {
            a1: 2.0,
            alpha_deg: 0.5,
            a2: 0.0,
        };
        let d = Dispersion::new(5, params, DispersionModel::DispersedMask).unwrap();
        assert_eq!(d.shifted_along(&[0.0; 5]).unwrap(), d);
        let s = d.shifted_along(&[0.0, 0.0, 0.4, 0.0, 0.0]).unwrap();
        let (moved, before) = (s.offset(2), d.offset(2));
        let along = (moved.0 - before.0).hypot(moved.1 - before.1);
        assert!((along - 0.4).abs() < 1e-12, "{along}");
        let refusal = |v: &[f64]| d.shifted_along(v).unwrap_err().to_string();
        let e = refusal(&[0.0; 4]);
        assert!(
            e.contains("4 values") && e.contains("5 (one per band)"),
            "{e}"
        );
        assert!(refusal(&[0.0, f64::NAN, 0.0, 0.0, 0.0]).contains("band 1"));
        let e = refusal(&[0.0, 0.0, 2.5, 0.0, 0.0]);
        assert!(e.contains("band 3") && e.contains("in order"), "{e}");
        assert!(refusal(&[-0.1, 0.0, 0.0, 0.0, 0.0]).contains("band 0"));
    }

    fn cols(d: &Dispersion) -> Vec<i32> {
        (0..d.bands()).map(|k| d.taps(k)[0].col).collect()
    }

    #[test]
    fn nominal_stride_two_gives_2k_and_width_w_plus_54() {
        let d = Dispersion::nominal(28, 2.0, DispersionModel::Rounded).unwrap();
        assert_eq!(cols(&d), (0..28).map(|k| 2 * k).collect::<Vec<_>>());
        assert_eq!(d.extra_cols(), 54);
        // integer offsets: the subpixel model degenerates to the same single taps
        let s = Dispersion::nominal(28, 2.0, DispersionModel::Subpixel).unwrap();
        assert!((0..28).all(|k| s.taps(k) == d.taps(k)));
    }

    #[test]
    fn paper_dispersion_rounds_half_to_even_and_matches_reference_offsets() {
        // a1 = 2.04, α = 0.5°: bands 0–12 at 2k, bands 13–27 at 2k+1 (seed-code notes §1.2)
        let d = Dispersion::new(
            28,
            DispersionParams {
                a1: 2.04,
                alpha_deg: 0.5,
                a2: 0.0,
            },
            DispersionModel::Rounded,
        )
        .unwrap();
        let want: Vec<i32> = (0..28)
            .map(|k| if k <= 12 { 2 * k } else { 2 * k + 1 })
            .collect();
        assert_eq!(cols(&d), want);
        assert_eq!(d.extra_cols(), 55);
        assert!((0..28).all(|k| d.taps(k)[0].row == 0));
        let d = Dispersion::new(
            28,
            DispersionParams {
                a1: 1.9,
                alpha_deg: 0.0,
                a2: 0.0,
            },
            DispersionModel::Rounded,
        )
        .unwrap();
        assert_eq!(
            cols(&d),
            vec![
                0, 2, 4, 6, 8, 10, 11, 13, 15, 17, 19, 21, 23, 25, 27, 28, 30, 32, 34, 36, 38, 40,
                42, 44, 46, 48, 49, 51
            ]
        );
        // ties go to even: 2.5 → 2, 3.5 → 4
        let d = Dispersion::new(
            3,
            DispersionParams {
                a1: 1.25,
                alpha_deg: 0.0,
                a2: 0.0,
            },
            DispersionModel::Rounded,
        )
        .unwrap();
        assert_eq!(cols(&d), vec![0, 1, 2]);
        let d = Dispersion::new(
            3,
            DispersionParams {
                a1: 1.75,
                alpha_deg: 0.0,
                a2: 0.0,
            },
            DispersionModel::Rounded,
        )
        .unwrap();
        assert_eq!(cols(&d), vec![0, 2, 4]);
    }

    #[test]
    fn subpixel_splits_light_between_neighbours_and_widens_by_ceil() {
        let d = Dispersion::new(
            3,
            DispersionParams {
                a1: 1.25,
                alpha_deg: 0.0,
                a2: 0.0,
            },
            DispersionModel::Subpixel,
        )
        .unwrap();
        // band 1 at 1.25: 0.75 at col 1, 0.25 at col 2
        assert_eq!(
            d.taps(1),
            &[
                Tap {
                    row: 0,
                    col: 1,
                    weight: 0.75
                },
                Tap {
                    row: 0,
                    col: 2,
                    weight: 0.25
                }
            ]
        );
        assert_eq!(d.extra_cols(), 3); // ceil(2.5)
        // a tilt sends light down (+row) for α > 0, weights sum to 1
        let d = Dispersion::new(
            5,
            DispersionParams {
                a1: 2.0,
                alpha_deg: 10.0,
                a2: 0.0,
            },
            DispersionModel::Subpixel,
        )
        .unwrap();
        let t = d.taps(4);
        assert!((t.iter().map(|t| t.weight).sum::<f32>() - 1.0).abs() < 1e-6);
        assert!(t.iter().any(|t| t.row == 1) && t.iter().all(|t| t.row >= 0));
    }

    #[test]
    fn a_dispersion_that_turns_back_is_refused_by_name() {
        let params = DispersionParams {
            a1: 2.0,
            alpha_deg: 0.0,
            a2: -0.04,
        };
        // slope 2 − 0.08·k: positive through band 24, zero at 25
        assert!(Dispersion::new(25, params, DispersionModel::DispersedMask).is_ok());
        for bands in [26, 28] {
            let err = Dispersion::new(bands, params, DispersionModel::DispersedMask)
                .unwrap_err()
                .to_string();
            assert!(err.contains("a2") && err.contains("in order"), "{err}");
        }
    }

    #[test]
    fn a_curved_dispersion_puts_band_k_at_a1_k_plus_a2_k_squared_along_alpha() {
        let params = DispersionParams {
            a1: 2.1,
            alpha_deg: 1.5,
            a2: -0.012,
        };
        let d = Dispersion::new(28, params, DispersionModel::DispersedMask).unwrap();
        let (s, c) = 1.5f64.to_radians().sin_cos();
        for k in [0, 1, 13, 27] {
            let along = 2.1 * k as f64 - 0.012 * (k * k) as f64;
            let (dc, dr) = d.offset(k);
            assert!((dc - along * c).abs() < 1e-12 && (dr - along * s).abs() < 1e-12);
            // the rates are the offsets' derivatives
            let h = 1e-6;
            let at = |a2: f64| {
                let p = DispersionParams { a2, ..params };
                Dispersion::new(28, p, DispersionModel::DispersedMask)
                    .unwrap()
                    .offset(k)
            };
            let ((pc, pr), (mc, mr)) = (at(-0.012 + h), at(-0.012 - h));
            let (rc, rr) = d.offset_rate_a2(k);
            assert!((rc - (pc - mc) / (2.0 * h)).abs() < 1e-6, "band {k}");
            assert!((rr - (pr - mr) / (2.0 * h)).abs() < 1e-6, "band {k}");
            let at_alpha = |alpha_deg: f64| {
                let p = DispersionParams {
                    alpha_deg,
                    ..params
                };
                Dispersion::new(28, p, DispersionModel::DispersedMask)
                    .unwrap()
                    .offset(k)
            };
            let ((pc, pr), (mc, mr)) = (at_alpha(1.5 + 1e-4), at_alpha(1.5 - 1e-4));
            let (rc, rr) = d.offset_rate_alpha_deg(k);
            assert!((rc - (pc - mc) / 2e-4).abs() < 1e-6, "α, band {k}");
            assert!((rr - (pr - mr) / 2e-4).abs() < 1e-6, "α, band {k}");
        }
        // a negative curvature narrows the detector: band 27 at 47.9 columns
        // instead of 56.7 (the taps reach ⌈·⌉)
        assert_eq!(d.extra_cols(), 48);
        let straight = Dispersion::new(28, DispersionParams { a2: 0.0, ..params }, d.model());
        assert_eq!(straight.unwrap().extra_cols(), 57);
    }

    #[test]
    fn bad_parameters_are_rejected() {
        assert!(
            Dispersion::new(
                0,
                DispersionParams {
                    a1: 2.0,
                    alpha_deg: 0.0,
                    a2: 0.0,
                },
                DispersionModel::Rounded
            )
            .is_err()
        );
        assert!(
            Dispersion::new(
                28,
                DispersionParams {
                    a1: -2.0,
                    alpha_deg: 0.0,
                    a2: 0.0,
                },
                DispersionModel::Rounded
            )
            .is_err()
        );
        assert!(
            Dispersion::new(
                28,
                DispersionParams {
                    a1: 1e9,
                    alpha_deg: 0.0,
                    a2: 0.0,
                },
                DispersionModel::Rounded
            )
            .is_err()
        );
        assert_eq!(
            "subpixel".parse::<DispersionModel>(),
            Ok(DispersionModel::Subpixel)
        );
        assert!("linear".parse::<DispersionModel>().is_err());
    }
}
