//! Where a band's light lies along the dispersion. A real camera's light is
//! continuous in wavelength: a "band" of a reconstruction is an interval of
//! wavelengths, and the prism spreads that interval along the dispersion,
//! between its neighbours' positions (2 px apart at the TSA camera's
//! stride). Every discrete model of ours (and the benchmark's simulator by
//! default) puts each band at one position, its centre.

use serde::{Deserialize, Serialize};

/// How each band's light is spread along the dispersion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BandSpread {
    /// At the band's own position alone (the discrete models' assumption).
    #[default]
    Point,
    /// Evenly from midway to the previous band's position to midway to the
    /// next's, half the light on either side: a spectrum constant within
    /// each band.
    Uniform,
    /// A hat from the previous band's position to the next's: a spectrum
    /// linear between band centres (the light of a pixel whose spectrum
    /// rises across a band then lands toward the rising side).
    Linear,
}

impl BandSpread {
    /// Every spread, with its name (the one registry of the names).
    pub const ALL: [(Self, &'static str); 3] = [
        (Self::Point, "point"),
        (Self::Uniform, "uniform"),
        (Self::Linear, "linear"),
    ];

    /// Every model's assumption (records leave it unwritten).
    pub fn is_point(&self) -> bool {
        *self == Self::Point
    }

    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(s, _)| *s == self)
            .map(|(_, n)| *n)
            .unwrap_or("point")
    }

    /// Band `k`'s light as (position (col, row) in detector pixels, share)
    /// pairs whose shares sum to 1, from every band's centre position
    /// `offsets`. The first and last bands' outer halves mirror their inner
    /// spacing; a single band stays a point. `per_half` positions sample each
    /// half of the spread (at their midpoints).
    pub fn positions(
        self,
        offsets: &[(f64, f64)],
        k: usize,
        per_half: usize,
    ) -> Vec<((f64, f64), f64)> {
        let centre = offsets[k];
        if self == Self::Point || offsets.len() < 2 || per_half == 0 {
            return vec![(centre, 1.0)];
        }
        let mirror = |other: (f64, f64)| (2.0 * centre.0 - other.0, 2.0 * centre.1 - other.1);
        let previous = if k == 0 {
            mirror(offsets[1])
        } else {
            offsets[k - 1]
        };
        let next = if k + 1 == offsets.len() {
            mirror(offsets[k - 1])
        } else {
            offsets[k + 1]
        };
        let mut out = Vec::with_capacity(2 * per_half);
        for end in [previous, next] {
            // t ∈ (0, 1): from the centre (t = 0) to the neighbour (t = 1)
            let samples: Vec<(f64, f64)> = (0..per_half)
                .map(|j| {
                    let t = (j as f64 + 0.5) / per_half as f64;
                    match self {
                        // out to the midpoint, evenly
                        Self::Uniform => (0.5 * t, 1.0),
                        // out to the neighbour, falling to zero there
                        _ => (t, 1.0 - t),
                    }
                })
                .collect();
            let total: f64 = samples.iter().map(|s| s.1).sum();
            for (t, w) in samples {
                let at = (
                    centre.0 + t * (end.0 - centre.0),
                    centre.1 + t * (end.1 - centre.1),
                );
                out.push((at, 0.5 * w / total));
            }
        }
        out
    }
}

impl std::str::FromStr for BandSpread {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        Self::ALL
            .iter()
            .find(|(_, n)| *n == text)
            .map(|(s, _)| *s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|(_, n)| *n).collect();
                format!(
                    "unknown band spread '{text}' (expected {})",
                    names.join(", ")
                )
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moments(p: &[((f64, f64), f64)]) -> (f64, f64, f64) {
        let w: f64 = p.iter().map(|x| x.1).sum();
        let m: f64 = p.iter().map(|x| x.0.0 * x.1).sum::<f64>() / w;
        let v: f64 = p.iter().map(|x| (x.0.0 - m).powi(2) * x.1).sum::<f64>() / w;
        (w, m, v)
    }

    #[test]
    fn spreads_keep_the_light_the_centre_and_have_their_widths() {
        // bands 2 px apart along x: a box of width 2 (variance 4/12) and a
        // hat of half-width 2 (variance 4/6)
        let offsets: Vec<(f64, f64)> = (0..5).map(|k| (2.0 * k as f64, 0.0)).collect();
        for k in 0..5 {
            let (w, m, v) = moments(&BandSpread::Point.positions(&offsets, k, 64));
            assert_eq!((w, m, v), (1.0, 2.0 * k as f64, 0.0));
            let (w, m, v) = moments(&BandSpread::Uniform.positions(&offsets, k, 64));
            assert!((w - 1.0).abs() < 1e-12 && (m - 2.0 * k as f64).abs() < 1e-12);
            assert!((v - 4.0 / 12.0).abs() < 1e-3, "uniform variance {v}");
            let (w, m, v) = moments(&BandSpread::Linear.positions(&offsets, k, 64));
            assert!((w - 1.0).abs() < 1e-12 && (m - 2.0 * k as f64).abs() < 1e-12);
            assert!((v - 4.0 / 6.0).abs() < 1e-3, "linear variance {v}");
        }
    }

    #[test]
    fn unequal_spacing_moves_the_light_toward_the_wider_side() {
        // band 1 has its next neighbour 3 px away and its previous 1 px:
        // half the light on each side, so the mean lies toward the next
        let offsets = [(0.0, 0.0), (1.0, 0.0), (4.0, 0.0)];
        let (_, m, _) = moments(&BandSpread::Uniform.positions(&offsets, 1, 64));
        assert!((m - (1.0 + 0.5 * (-0.25 + 0.75))).abs() < 1e-9, "{m}");
        // along a tilted dispersion the spread follows the tilt
        let tilted = [(0.0, 0.0), (2.0, 0.2), (4.0, 0.4)];
        for (at, _) in BandSpread::Linear.positions(&tilted, 1, 8) {
            assert!((at.1 - 0.1 * at.0).abs() < 1e-12);
        }
    }

    #[test]
    fn names_round_trip_and_unknown_ones_are_refused() {
        for (s, n) in BandSpread::ALL {
            assert_eq!(n.parse::<BandSpread>().unwrap(), s);
            assert_eq!(s.name(), n);
            assert_eq!(
                serde_json::to_string(&s).unwrap(),
                format!("\"{n}\""),
                "serde and the registry agree"
            );
        }
        let err = "box".parse::<BandSpread>().unwrap_err();
        assert!(err.contains("'box'") && err.contains("uniform"), "{err}");
    }
}
