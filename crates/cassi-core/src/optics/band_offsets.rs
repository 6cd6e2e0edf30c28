//! A prism's band positions held fixed: each band's departure along the
//! dispersion from the straight line a1·k (+ a2·k²) the calibration fits.
//! Why: a prism's dispersion need not be a low-order polynomial in the
//! band index; where its shape is known (a monochromator scan of the
//! camera, or the band-shift fit of several snapshots,
//! `calib::fit_band_shifts`) the calibration can hold it and fit the line,
//! the pose and the blur as before.
//!
//! A table is read as positions or as departures alike: its own line
//! through band 0 (least squares) is removed, since a common shift is the
//! mask's dx and a slope is a1 — the calibration fits both, so a1 keeps its
//! meaning (the bands' mean spacing) and band 0 lands where the mask's pose
//! says, as without a table.

use serde::{Deserialize, Serialize};

use crate::error::{CassiError, Result, shape_error};

/// Each band's fixed departure (px along the dispersion) from a1·k + a2·k².
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BandOffsets {
    /// δₖ, band k's departure; δ₀ = 0 and Σ k·δₖ = 0 (no line left in it).
    pub offsets: Vec<f64>,
    /// The line t₀ + s·k removed from the table as given: [t₀, s].
    pub table_line: [f64; 2],
}

impl BandOffsets {
    /// Departures beyond this many pixels are refused: a table in another
    /// unit, or a dispersion a2 should carry.
    pub const MAX_DEPARTURE_PX: f64 = 4.0;
    /// A table rising more than this many nominal strides per band is
    /// refused: wavelengths, or positions in another unit.
    pub const MAX_TABLE_STRIDES: f64 = 2.0;

    /// The departures of `table` (one position or departure per band, px
    /// along the dispersion) from its own least-squares line through band 0;
    /// `stride` the nominal dispersion (px per band) its slope is checked
    /// against: positions rise about a stride per band, departures not at
    /// all; one falling by more than half a stride lists the bands in
    /// reverse.
    pub fn from_table(table: &[f64], stride: f64) -> Result<Self> {
        if table.len() < 2 {
            return Err(shape_error(
                "the band-offset table",
                format!("{} values", table.len()),
                "one per band (at least 2)",
            ));
        }
        if let Some((k, &v)) = table.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(CassiError::NonFinite {
                what: "the band-offset table".into(),
                value: v as f32,
                location: format!("band {k}"),
            });
        }
        let t0 = table[0];
        let (kt, kk) = table
            .iter()
            .enumerate()
            .fold((0.0, 0.0), |(kt, kk), (k, t)| {
                let k = k as f64;
                (kt + k * (t - t0), kk + k * k)
            });
        let slope = kt / kk;
        if slope > Self::MAX_TABLE_STRIDES * stride {
            return Err(CassiError::InvalidParameter {
                name: "band-offset table slope",
                value: slope,
                reason: format!(
                    "the table rises {slope:.3} per band, more than {} times the nominal stride \
                     {stride} px; band positions are pixels along the dispersion — wavelengths \
                     or another unit?",
                    Self::MAX_TABLE_STRIDES
                ),
            });
        }
        if slope < -0.5 * stride {
            return Err(CassiError::InvalidParameter {
                name: "band-offset table slope",
                value: slope,
                reason: "the positions fall with the band index: list band 0 (the one at the \
                         mask's own position) first"
                    .into(),
            });
        }
        let offsets: Vec<f64> = table
            .iter()
            .enumerate()
            .map(|(k, t)| t - t0 - slope * k as f64)
            .collect();
        if let Some((k, &d)) = offsets
            .iter()
            .enumerate()
            .find(|(_, d)| d.abs() > Self::MAX_DEPARTURE_PX)
        {
            return Err(CassiError::InvalidParameter {
                name: "band offset",
                value: d,
                reason: format!(
                    "band {k} departs {d:+.3} px from the table's line through band 0; at most \
                     {} px (a curved prism's bow is --dispersion-a2's)",
                    Self::MAX_DEPARTURE_PX
                ),
            });
        }
        Ok(Self {
            offsets,
            table_line: [t0, slope],
        })
    }

    pub fn bands(&self) -> usize {
        self.offsets.len()
    }

    pub fn as_slice(&self) -> &[f64] {
        &self.offsets
    }

    /// The departures' RMS, px.
    pub fn rms(&self) -> f64 {
        (self.offsets.iter().map(|d| d * d).sum::<f64>() / self.bands() as f64).sqrt()
    }

    /// An error unless these are `bands` finite departures (a record read
    /// back is checked as a table is).
    pub fn check(&self, bands: usize) -> Result<()> {
        if self.bands() != bands {
            return Err(shape_error(
                "the band offsets",
                format!("{} values", self.bands()),
                format!("{bands} (one per band of the cube)"),
            ));
        }
        // departures have no slope to check
        let again = Self::from_table(&self.offsets, f64::INFINITY)?;
        let moved = again
            .offsets
            .iter()
            .zip(&self.offsets)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if moved > 1e-6 {
            return Err(CassiError::Meaningless {
                what: "the band offsets".into(),
                reason: format!(
                    "they hold a line through band 0 (moved {moved:.2e} px by removing it); \
                     build them with BandOffsets::from_table"
                ),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_keeps_its_shape_and_loses_its_line() {
        let shape = [0.0, 0.1, -0.2, 0.05, 0.3, -0.1];
        // positions: 2.1 px per band from 7 px, plus the shape
        let table: Vec<f64> = shape
            .iter()
            .enumerate()
            .map(|(k, s)| 7.0 + 2.1 * k as f64 + s)
            .collect();
        let o = BandOffsets::from_table(&table, 2.0).unwrap();
        assert_eq!(o.offsets[0], 0.0);
        let ks: f64 = o
            .offsets
            .iter()
            .enumerate()
            .map(|(k, d)| k as f64 * d)
            .sum();
        assert!(ks.abs() < 1e-12, "{ks}");
        // positions and departures give the same offsets
        let d = BandOffsets::from_table(&shape, 2.0).unwrap();
        for (a, b) in o.offsets.iter().zip(&d.offsets) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!((o.table_line[1] - d.table_line[1] - 2.1).abs() < 1e-12);
        assert_eq!(o.table_line[0], 7.0);
        // what it removed is a line: the shape's own part off it is kept
        assert!(o.rms() > 0.1);
        // idempotent: its own offsets pass the check
        o.check(6).unwrap();
        let mut with_line = o.clone();
        with_line.offsets[5] += 0.5;
        assert!(with_line.check(6).unwrap_err().to_string().contains("line"));
    }

    #[test]
    fn bad_tables_are_refused_by_name() {
        let refused = |t: &[f64]| BandOffsets::from_table(t, 2.0).unwrap_err().to_string();
        assert!(refused(&[1.0]).contains("one per band"));
        assert!(refused(&[0.0, f64::NAN, 1.0]).contains("band 1"));
        // wavelengths in nm
        let nm: Vec<f64> = (0..28).map(|k| 450.0 + 7.5 * k as f64).collect();
        assert!(refused(&nm).contains("wavelengths"));
        let reversed: Vec<f64> = (0..28).map(|k| 60.0 - 2.0 * k as f64).collect();
        assert!(refused(&reversed).contains("band 0"));
        assert!(refused(&[0.0, 2.0, 9.0, 6.0, 8.0]).contains("band 2"));
        let o = BandOffsets::from_table(&[0.0, 0.1, 0.0], 2.0).unwrap();
        assert!(
            o.check(4)
                .unwrap_err()
                .to_string()
                .contains("4 (one per band")
        );
    }
}
