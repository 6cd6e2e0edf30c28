//! The mismatch between the nominal model and the true instrument, in the
//! units users see: pixels and degrees.

use serde::{Deserialize, Serialize};

use crate::error::{CassiError, Result};

/// The largest |θ| and |α| (degrees) accepted: beyond this the small-misalignment
/// model (and every calibration search range) is meaningless.
pub const MAX_ANGLE_DEG: f64 = 45.0;

/// The open range of dispersion slopes (a1, and an instrument's nominal
/// stride) accepted, pixels per band: outside it the band count or the
/// detector width is absurd (a stride of 0.001 px would mean 55,000 bands on
/// a 256-column mask with 55 extra columns).
pub const MIN_SLOPE: f64 = 1e-3;
pub const MAX_SLOPE: f64 = 1e3;

/// The widest optical blur accepted, detector pixels: beyond it a CASSI
/// image holds no code worth calibrating.
pub const MAX_BLUR_SIGMA_PX: f64 = 8.0;

/// Rigid placement of the mask relative to its nominal position
/// (docs/CONVENTIONS.md):
/// a mask point u = (col, row) moves to `R(θ)(u − c) + c + (dx, dy)`, with c the
/// mask centre ((W−1)/2, (H−1)/2).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MaskPose {
    /// Shift along columns, pixels, + = right.
    pub dx: f64,
    /// Shift along rows, pixels, + = down.
    pub dy: f64,
    /// Rotation in degrees; R(θ) = [[cos, −sin], [sin, cos]] on (col, row),
    /// so + turns the +col axis toward +row (clockwise on screen).
    pub theta_deg: f64,
}

/// Dispersion of the prism: band k lands `d_k = a1·k + a2·k²` detector
/// pixels along the dispersion axis, at column offset `d_k·cos α` and row
/// offset `d_k·sin α`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DispersionParams {
    /// Pixels per band along the dispersion axis.
    pub a1: f64,
    /// Angle of the dispersion axis from the +col axis toward +row, degrees.
    pub alpha_deg: f64,
    /// Curvature, pixels per band² (0 = a straight dispersion); absent in
    /// files written before it was modelled.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub a2: f64,
}

/// The largest |a2| accepted, px per band²: a guard against unit mistakes
/// (0.5 moves band 10 by 50 px, beyond any prism's departure from a
/// straight line) that leaves room for the oversampled simulators, whose
/// fine grids count 2–4 pixels per detector pixel.
pub const MAX_DISPERSION_A2: f64 = 0.5;

/// A dispersion curvature a2 (px per band²) within ±[`MAX_DISPERSION_A2`].
pub fn validate_curvature(a2: f64) -> Result<()> {
    finite("a2", a2)?;
    if a2.abs() > MAX_DISPERSION_A2 {
        return Err(CassiError::InvalidParameter {
            name: "a2",
            value: a2,
            reason: format!(
                "the dispersion's curvature must lie within ±{MAX_DISPERSION_A2} pixels per band²"
            ),
        });
    }
    Ok(())
}

pub(crate) fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// One component of the mismatch vector ψ: the one registry of its name in
/// files, its symbol and unit for people, its display precision and how to
/// read and write it on a [`Mismatch`]. Tables, CSV, figures, the CLI and the
/// calibration's free-parameter sets iterate [`Parameter::ALL`] instead of
/// listing the fields, so a new parameter is one variant here plus its
/// physics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Parameter {
    Dx,
    Dy,
    ThetaDeg,
    A1,
    AlphaDeg,
    /// The optical blur's Gaussian σ on the detector (0 = a sharp image).
    BlurSigmaPx,
    /// The dispersion's curvature a2 (band k at a1·k + a2·k²).
    A2,
}

impl Parameter {
    /// Every parameter, in the order tables and files list them.
    pub const ALL: [Parameter; 7] = [
        Self::Dx,
        Self::Dy,
        Self::ThetaDeg,
        Self::A1,
        Self::AlphaDeg,
        Self::BlurSigmaPx,
        Self::A2,
    ];

    /// The parameters the calibration presets fit: every one but the
    /// curvature a2, which they hold at the value they are given (0 unless
    /// a camera's design or a study says otherwise).
    pub const CALIBRATED: [Parameter; 6] = {
        // the first six of ALL: a2 is listed last there
        assert!(matches!(Self::ALL[6], Self::A2));
        let mut out = [Self::A2; 6];
        let mut i = 0;
        while i < out.len() {
            out[i] = Self::ALL[i];
            i += 1;
        }
        out
    };

    /// The parameter's position in [`Self::ALL`] (tables indexed by it).
    pub fn index(self) -> usize {
        self as usize
    }

    pub fn get(self, m: &Mismatch) -> f64 {
        match self {
            Self::Dx => m.dx,
            Self::Dy => m.dy,
            Self::ThetaDeg => m.theta_deg,
            Self::A1 => m.a1,
            Self::AlphaDeg => m.alpha_deg,
            Self::BlurSigmaPx => m.blur_sigma_px,
            Self::A2 => m.a2,
        }
    }

    pub fn set(self, m: &mut Mismatch, v: f64) {
        match self {
            Self::Dx => m.dx = v,
            Self::Dy => m.dy = v,
            Self::ThetaDeg => m.theta_deg = v,
            Self::A1 => m.a1 = v,
            Self::AlphaDeg => m.alpha_deg = v,
            Self::BlurSigmaPx => m.blur_sigma_px = v,
            Self::A2 => m.a2 = v,
        }
    }

    /// The field name in JSON files and CSV headers (`theta_deg`).
    pub fn key(self) -> &'static str {
        match self {
            Self::Dx => "dx",
            Self::Dy => "dy",
            Self::ThetaDeg => "theta_deg",
            Self::A1 => "a1",
            Self::AlphaDeg => "alpha_deg",
            Self::BlurSigmaPx => "blur_sigma_px",
            Self::A2 => "a2",
        }
    }

    /// The symbol people read (`θ`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Dx => "dx",
            Self::Dy => "dy",
            Self::ThetaDeg => "θ",
            Self::A1 => "a1",
            Self::AlphaDeg => "α",
            Self::BlurSigmaPx => "blur",
            Self::A2 => "a2",
        }
    }

    /// The unit, as printed after a value ("px", "°", "px/band").
    pub fn unit(self) -> &'static str {
        match self {
            Self::Dx | Self::Dy | Self::BlurSigmaPx => "px",
            Self::ThetaDeg | Self::AlphaDeg => "°",
            Self::A1 => "px/band",
            Self::A2 => "px/band²",
        }
    }

    /// `θ (°)`: the symbol with its unit, for table headers and axes.
    pub fn label(self) -> String {
        format!("{} ({})", self.name(), self.unit())
    }

    /// Decimals shown for a value (a1 needs more than a shift).
    pub fn decimals(self) -> usize {
        match self {
            Self::Dx | Self::Dy | Self::ThetaDeg | Self::BlurSigmaPx => 3,
            Self::A1 => 4,
            Self::A2 => 5,
            Self::AlphaDeg => 2,
        }
    }

    /// Whether the parameter is an offset from zero (printed signed) rather
    /// than a magnitude (a1, the blur width).
    pub fn signed(self) -> bool {
        !matches!(self, Self::A1 | Self::BlurSigmaPx)
    }

    /// The least value the parameter can take, if any: a blur's width is
    /// never negative.
    pub fn lower_bound(self) -> Option<f64> {
        matches!(self, Self::BlurSigmaPx).then_some(0.0)
    }

    /// Whether files may leave the parameter out (it then takes its nominal
    /// value): files written before the parameter existed stay readable.
    pub fn optional_in_files(self) -> bool {
        matches!(self, Self::BlurSigmaPx | Self::A2)
    }

    /// `v` at the parameter's precision, signed when it is an offset.
    pub fn format(self, v: f64) -> String {
        let d = self.decimals();
        if self.signed() {
            format!("{v:+.d$}")
        } else {
            format!("{v:.d$}")
        }
    }

    /// Whether a line describing `m` shows the parameter: all of them but a
    /// straight dispersion's curvature (0), which only clutters.
    pub fn shown(self, m: &Mismatch) -> bool {
        self != Self::A2 || m.a2 != 0.0
    }

    /// `dx +1.500 px  dy … α +0.50°`: a whole mismatch on one line (a2
    /// only when the dispersion is curved).
    pub fn format_all(m: &Mismatch) -> String {
        Self::ALL
            .iter()
            .filter(|p| p.shown(m))
            .map(|p| {
                let gap = if p.unit() == "°" { "" } else { " " };
                format!("{} {}{gap}{}", p.name(), p.format(p.get(m)), p.unit())
            })
            .collect::<Vec<_>>()
            .join("  ")
    }
}

/// The mismatch vector ψ = (dx, dy, θ, a1, α, σ_blur): the mask's pose, the
/// prism's dispersion and the optical blur of the true instrument against
/// the nominal model (aligned, dispersion `stride` px/band along the rows,
/// a sharp image).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Mismatch {
    pub dx: f64,
    pub dy: f64,
    pub theta_deg: f64,
    pub a1: f64,
    pub alpha_deg: f64,
    /// Gaussian σ of the optical blur on the detector, pixels (0 = none);
    /// absent in files written before blur was modelled.
    #[serde(default)]
    pub blur_sigma_px: f64,
    /// The dispersion's curvature, px per band² (0 = straight); absent in
    /// files written before it was modelled, and not written when 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub a2: f64,
}

impl Mismatch {
    /// No mismatch for an instrument of nominal stride `stride`.
    pub const fn nominal(stride: f64) -> Self {
        Self {
            dx: 0.0,
            dy: 0.0,
            theta_deg: 0.0,
            a1: stride,
            alpha_deg: 0.0,
            blur_sigma_px: 0.0,
            a2: 0.0,
        }
    }

    /// The paper's injected mismatch (§5.1): dx 1.5 px, dy 1.0 px, θ 0.3°, a1 2.04, α 0.5°.
    pub const fn paper() -> Self {
        Self {
            dx: 1.5,
            dy: 1.0,
            theta_deg: 0.3,
            a1: 2.04,
            alpha_deg: 0.5,
            blur_sigma_px: 0.0,
            a2: 0.0,
        }
    }

    pub fn pose(&self) -> MaskPose {
        MaskPose {
            dx: self.dx,
            dy: self.dy,
            theta_deg: self.theta_deg,
        }
    }

    /// The same instrument described from a band of the frame's rows whose
    /// centre lies `rows_below` rows below the frame's centre: the pose
    /// turns about the band's own centre (see `optics::warp`), so the shift
    /// picks up (R(θ) − I)(0, h) — dx − sin θ·h, dy + (cos θ − 1)·h — and
    /// nothing else changes (the dispersion and the blur are the same at
    /// every row).
    pub fn seen_from_rows_below(&self, rows_below: f64) -> Self {
        let t = self.theta_deg.to_radians();
        Self {
            dx: self.dx - t.sin() * rows_below,
            dy: self.dy + (t.cos() - 1.0) * rows_below,
            ..*self
        }
    }

    pub fn dispersion(&self) -> DispersionParams {
        DispersionParams {
            a1: self.a1,
            alpha_deg: self.alpha_deg,
            a2: self.a2,
        }
    }

    /// Scales the deviation from nominal by `factor` (sensitivity sweeps).
    pub fn scaled_from_nominal(&self, stride: f64, factor: f64) -> Self {
        Self {
            dx: self.dx * factor,
            dy: self.dy * factor,
            theta_deg: self.theta_deg * factor,
            a1: stride + (self.a1 - stride) * factor,
            alpha_deg: self.alpha_deg * factor,
            blur_sigma_px: self.blur_sigma_px * factor,
            a2: self.a2 * factor,
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.pose().validate()?;
        self.dispersion().validate()?;
        finite("blur_sigma_px", self.blur_sigma_px)?;
        if !(0.0..=MAX_BLUR_SIGMA_PX).contains(&self.blur_sigma_px) {
            return Err(CassiError::InvalidParameter {
                name: "blur_sigma_px",
                value: self.blur_sigma_px,
                reason: format!(
                    "the blur width must lie in [0, {MAX_BLUR_SIGMA_PX}] detector pixels"
                ),
            });
        }
        Ok(())
    }

    /// The instrument without its blur (the sharp model's parameters).
    pub fn sharp(&self) -> Self {
        Self {
            blur_sigma_px: 0.0,
            ..*self
        }
    }
}

fn finite(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(CassiError::InvalidParameter {
            name,
            value,
            reason: "must be a finite number".into(),
        })
    }
}

fn angle(name: &'static str, value: f64) -> Result<()> {
    finite(name, value)?;
    if value.abs() > MAX_ANGLE_DEG {
        return Err(CassiError::InvalidParameter {
            name,
            value,
            reason: format!("|{name}| must be at most {MAX_ANGLE_DEG}° (angles are in degrees)"),
        });
    }
    Ok(())
}

impl MaskPose {
    pub fn validate(&self) -> Result<()> {
        finite("dx", self.dx)?;
        finite("dy", self.dy)?;
        angle("theta_deg", self.theta_deg)
    }

    pub fn is_identity(&self) -> bool {
        self.dx == 0.0 && self.dy == 0.0 && self.theta_deg == 0.0
    }
}

impl DispersionParams {
    /// How far band `band` (0 = the reference band; fractional for a band
    /// centre) lands along the dispersion axis, px: a1·k + a2·k², the one
    /// place the dispersion's shape is written.
    pub fn along(&self, band: f64) -> f64 {
        self.a1 * band + self.a2 * (band * band)
    }

    pub fn validate(&self) -> Result<()> {
        finite("a1", self.a1)?;
        if !(MIN_SLOPE < self.a1 && self.a1 < MAX_SLOPE) {
            return Err(CassiError::InvalidParameter {
                name: "a1",
                value: self.a1,
                reason: format!(
                    "the dispersion slope must lie between {MIN_SLOPE} and {MAX_SLOPE} pixels \
                     per band"
                ),
            });
        }
        angle("alpha_deg", self.alpha_deg)?;
        validate_curvature(self.a2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_registry_names_every_field_as_the_json_does() {
        let mut m = Mismatch::paper();
        m.a2 = 0.01;
        let json = serde_json::to_value(m).unwrap();
        let object = json.as_object().unwrap();
        assert_eq!(object.len(), Parameter::ALL.len());
        for p in Parameter::ALL {
            assert_eq!(object[p.key()].as_f64().unwrap(), p.get(&m), "{p:?}");
            p.set(&mut m, 7.0);
            assert_eq!(p.get(&m), 7.0);
        }
        assert_eq!(
            Parameter::format_all(&Mismatch::paper()),
            "dx +1.500 px  dy +1.000 px  θ +0.300°  a1 2.0400 px/band  α +0.50°  blur 0.000 px"
        );
        assert_eq!(Parameter::ThetaDeg.label(), "θ (°)");
    }

    #[test]
    fn the_curvature_is_written_only_when_there_is_one_and_refused_out_of_range() {
        // a straight dispersion's files read and write as before
        let straight = serde_json::to_value(Mismatch::paper()).unwrap();
        assert!(straight.get("a2").is_none());
        let back: Mismatch = serde_json::from_value(straight).unwrap();
        assert_eq!(back.a2, 0.0);
        let curved = Mismatch {
            a2: -0.008,
            ..Mismatch::paper()
        };
        let json = serde_json::to_value(curved).unwrap();
        assert_eq!(json["a2"].as_f64(), Some(-0.008));
        assert_eq!(serde_json::from_value::<Mismatch>(json).unwrap(), curved);
        assert_eq!(curved.dispersion().a2, -0.008);
        assert!(Parameter::format_all(&curved).ends_with("a2 -0.00800 px/band²"));
        assert!(!Parameter::format_all(&Mismatch::paper()).contains("a2"));
        for bad in [0.6, -0.6, f64::NAN] {
            let e = Mismatch { a2: bad, ..curved }.validate().unwrap_err();
            assert!(e.to_string().contains("a2"), "{e}");
        }
        assert!(Mismatch { a2: 0.5, ..curved }.validate().is_ok());
    }

    #[test]
    fn json_round_trip_uses_unit_bearing_names() {
        let m = Mismatch::paper();
        let s = serde_json::to_string(&m).unwrap();
        assert_eq!(
            s,
            r#"{"dx":1.5,"dy":1.0,"theta_deg":0.3,"a1":2.04,"alpha_deg":0.5,"blur_sigma_px":0.0}"#
        );
        let back: Mismatch = serde_json::from_str(&s).unwrap();
        assert_eq!(back, m);
        // files from before the blur was modelled read as a sharp instrument
        let old: Mismatch = serde_json::from_str(
            r#"{"dx":1.5,"dy":1.0,"theta_deg":0.3,"a1":2.04,"alpha_deg":0.5}"#,
        )
        .unwrap();
        assert_eq!(old, m);
    }

    #[test]
    fn absurd_values_are_rejected_with_the_parameter_named() {
        let bad = [
            Mismatch {
                theta_deg: 46.0,
                ..Mismatch::paper()
            },
            Mismatch {
                a1: 0.0,
                ..Mismatch::paper()
            },
            Mismatch {
                a1: -1.0,
                ..Mismatch::paper()
            },
            Mismatch {
                alpha_deg: -50.0,
                ..Mismatch::paper()
            },
            Mismatch {
                dx: f64::NAN,
                ..Mismatch::paper()
            },
            Mismatch {
                blur_sigma_px: -0.1,
                ..Mismatch::paper()
            },
            Mismatch {
                blur_sigma_px: 9.0,
                ..Mismatch::paper()
            },
        ];
        let names = [
            "theta_deg",
            "a1",
            "a1",
            "alpha_deg",
            "dx",
            "blur_sigma_px",
            "blur_sigma_px",
        ];
        for (m, name) in bad.iter().zip(names) {
            let e = m.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        assert!(Mismatch::paper().validate().is_ok());
    }

    #[test]
    fn scaling_keeps_nominal_a1() {
        let m = Mismatch::paper().scaled_from_nominal(2.0, 2.0);
        assert!((m.a1 - 2.08).abs() < 1e-12 && m.dx == 3.0 && m.theta_deg == 0.6);
    }
}
