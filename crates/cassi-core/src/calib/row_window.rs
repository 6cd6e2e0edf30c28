//! A band of the frame's rows as an instrument of its own. The dispersion
//! moves light along a row, not across rows, so the middle rows of a
//! measurement, with the same rows of the mask, are a smaller measurement
//! of the same camera, its pose turned about the band's own centre
//! ([`Mismatch::seen_from_rows_below`]). Stages whose cost follows the
//! frame's area run on a band: the blur pass (`blur_pass.rs`) and, on
//! frames taller than the benchmark's, the default preset's search stages
//! (`default.rs`).

use super::score::CalibrationProblem;
use crate::cube::{Mask, Measurement};
use crate::error::Result;
use crate::params::Mismatch;

/// The frame's rows `first..end`, whose rows `margin` in from either end
/// are the band proper (the margin's own light comes partly from outside
/// the band, which the band's model cannot see).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RowWindow {
    pub first: usize,
    pub end: usize,
    pub margin: usize,
}

impl RowWindow {
    /// `kept` middle rows of a frame of `rows` rows with `cols` columns, or
    /// `None` when they and their margin would cover it. The margin holds
    /// every way light reaches a kept row from outside the band at `at`:
    /// the pose's shift and tilt across the columns, the dispersion's tilt
    /// over the bands, the blur's and a high-pass's reach (`high_pass_px`,
    /// 0 for a score without one), and the interpolation's pixel, plus a
    /// spare row.
    pub fn centred(
        kept: usize,
        rows: usize,
        cols: usize,
        bands: usize,
        at: &Mismatch,
        high_pass_px: f64,
    ) -> Option<Self> {
        let reach = at.dy.abs()
            + at.theta_deg.to_radians().sin().abs() * cols as f64 / 2.0
            + at.a1.abs() * bands as f64 * at.alpha_deg.to_radians().sin().abs()
            + 4.0 * at.blur_sigma_px
            + 4.0 * high_pass_px
            + 2.0;
        let margin = reach.ceil() as usize;
        if kept == 0 || kept + 2 * margin >= rows {
            return None;
        }
        let first = (rows - kept) / 2 - margin;
        Some(Self {
            first,
            end: first + kept + 2 * margin,
            margin,
        })
    }

    /// [`RowWindow::centred`]'s band, moved to where `y`'s rows hold the
    /// scene when the middle ones hold little of it: to the band of as many
    /// rows with the most pixel-scale detail (squared differences between
    /// neighbouring pixels — the code's imprint, which a dark or flat
    /// region lacks) when that band holds more than
    /// [`MIDDLE_DETAIL_SHORTFALL`] times the middle one's. A frame whose
    /// middle holds its share keeps the middle (the real snapshots do: the
    /// band only moves for a frame the middle would leave blind).
    pub fn centred_unless_blind(
        kept: usize,
        y: &Measurement,
        bands: usize,
        at: &Mismatch,
        high_pass_px: f64,
    ) -> Option<Self> {
        let (rows, cols) = y.shape();
        let middle = Self::centred(kept, rows, cols, bands, at, high_pass_px)?;
        let detail = row_detail(y);
        // prefix sums: the detail of the kept rows of the band starting at `first`
        let mut below = vec![0.0f64; rows + 1];
        for (r, d) in detail.iter().enumerate() {
            below[r + 1] = below[r] + d;
        }
        let kept_detail =
            |first: usize| below[first + middle.margin + kept] - below[first + middle.margin];
        let span = middle.end - middle.first;
        let centre = middle.first;
        let best = (0..=rows - span)
            .max_by(|&a, &b| {
                kept_detail(a)
                    .total_cmp(&kept_detail(b))
                    // ties to the band nearer the middle
                    .then(b.abs_diff(centre).cmp(&a.abs_diff(centre)))
            })
            .unwrap_or(centre);
        if kept_detail(best) > MIDDLE_DETAIL_SHORTFALL * kept_detail(centre) {
            Some(Self {
                first: best,
                end: best + span,
                margin: middle.margin,
            })
        } else {
            Some(middle)
        }
    }

    /// Rows the band's centre lies below the frame's.
    pub fn centre_below(&self, rows: usize) -> f64 {
        (self.first + self.end) as f64 / 2.0 - rows as f64 / 2.0
    }

    /// The band's kept rows, counted from its first row.
    pub fn kept(&self) -> (usize, usize) {
        (self.margin, self.end - self.first - self.margin)
    }
}

/// How much more pixel-scale detail another band must hold than the middle
/// one before [`RowWindow::centred_unless_blind`] moves there: a safety net
/// for a frame whose middle is dark or flat, not a search for the best band
/// (the search stages were tuned on middle bands).
pub(crate) const MIDDLE_DETAIL_SHORTFALL: f64 = 2.0;

/// Each row's squared differences to its right and lower neighbours.
fn row_detail(y: &Measurement) -> Vec<f64> {
    let (rows, cols) = y.shape();
    let v = y.as_slice();
    (0..rows)
        .map(|r| {
            let row = &v[r * cols..(r + 1) * cols];
            let along: f64 = row.windows(2).map(|p| f64::from(p[1] - p[0]).powi(2)).sum();
            let across: f64 = if r + 1 < rows {
                row.iter()
                    .zip(&v[(r + 1) * cols..(r + 2) * cols])
                    .map(|(a, b)| f64::from(b - a).powi(2))
                    .sum()
            } else {
                0.0
            };
            along + across
        })
        .collect()
}

/// A problem's rows `window` cut out: its measurement and its nominal
/// mask's same rows, owned, so that [`RowBand::problem`] can lend them.
pub(crate) struct RowBand {
    /// Rows the band's centre lies below the frame's.
    pub centre_below: f64,
    measurement: Measurement,
    mask: Mask,
}

impl RowBand {
    pub fn cut(problem: &CalibrationProblem<'_>, window: RowWindow) -> Result<Self> {
        let rows = problem.measurement.rows();
        Ok(Self {
            centre_below: window.centre_below(rows),
            measurement: problem.measurement.rows_range(window.first, window.end)?,
            mask: problem
                .nominal_mask()
                .rows_range(window.first, window.end)?,
        })
    }

    /// `frame`'s problem on the band (its model and cancel flag).
    pub fn problem<'b>(&'b self, frame: &CalibrationProblem<'b>) -> Result<CalibrationProblem<'b>> {
        Ok(CalibrationProblem {
            measurement: &self.measurement,
            nominal: frame.nominal.with_mask(&self.mask)?,
            cancel: frame.cancel,
        })
    }

    /// ψ of the whole frame as the band sees it.
    pub fn seen(&self, frame_psi: &Mismatch) -> Mismatch {
        frame_psi.seen_from_rows_below(self.centre_below)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_keeps_a_margin_that_grows_with_the_pose() {
        let aligned = Mismatch {
            blur_sigma_px: 0.5,
            ..Mismatch::nominal(2.0)
        };
        let w = RowWindow::centred(64, 256, 310, 28, &aligned, 0.5).unwrap();
        assert_eq!((w.first + w.margin, w.end - w.margin), (96, 160));
        assert_eq!(w.kept(), (w.margin, w.margin + 64));
        assert_eq!(w.centre_below(256), 0.0);
        let moved = Mismatch {
            dy: 2.5,
            theta_deg: 0.8,
            alpha_deg: 1.0,
            ..aligned
        };
        let wide = RowWindow::centred(64, 256, 310, 28, &moved, 0.5).unwrap();
        // dy, θ across half the columns and α over the bands add ≈ 5.7 rows
        assert!(
            wide.margin >= w.margin + 5,
            "{} vs {}",
            wide.margin,
            w.margin
        );
        // a window that with its margin would cover the frame is the frame
        assert_eq!(RowWindow::centred(250, 256, 310, 28, &aligned, 0.5), None);
    }

    /// The band stays in the middle of a frame whose rows all hold the
    /// code's detail, and moves to the detail when the middle is dark.
    #[test]
    fn the_band_leaves_a_dark_middle_for_the_rows_that_hold_the_scene() {
        let (rows, cols) = (200, 60);
        let code = |r: usize, c: usize| ((r * 31 + c * 17) % 7) as f32 / 6.0;
        let textured = Measurement::from_vec(
            rows,
            cols,
            (0..rows * cols).map(|i| code(i / cols, i % cols)).collect(),
        )
        .unwrap();
        let at = Mismatch::nominal(2.0);
        let middle = RowWindow::centred(40, rows, cols, 8, &at, 0.0).unwrap();
        assert_eq!(
            RowWindow::centred_unless_blind(40, &textured, 8, &at, 0.0),
            Some(middle)
        );
        // the scene only in the top 60 rows: the middle band sees nothing
        let top = Measurement::from_vec(
            rows,
            cols,
            (0..rows * cols)
                .map(|i| {
                    if i / cols < 60 {
                        code(i / cols, i % cols)
                    } else {
                        0.0
                    }
                })
                .collect(),
        )
        .unwrap();
        let moved = RowWindow::centred_unless_blind(40, &top, 8, &at, 0.0).unwrap();
        let (first, end) = (moved.first + moved.margin, moved.end - moved.margin);
        assert!(end <= 61 && end - first == 40, "{moved:?}");
        assert_eq!(
            (moved.margin, moved.end - moved.first),
            (middle.margin, middle.end - middle.first)
        );
        // a frame the band and its margin would cover is the frame
        assert_eq!(
            RowWindow::centred_unless_blind(197, &top, 8, &at, 0.0),
            None
        );
    }

    /// Seen from a band and back is the frame's own ψ, and a band off the
    /// centre sees a turned mask shifted along the rows.
    #[test]
    fn a_band_sees_the_frames_pose_from_its_centre_and_back() {
        let psi = Mismatch {
            dx: 0.3,
            dy: -0.2,
            theta_deg: 0.5,
            ..Mismatch::nominal(2.0)
        };
        let code = (0..40 * 40).map(|i| ((i * 7) % 5) as f32 / 4.0).collect();
        let mask = Mask::from_vec(40, 40, code).unwrap();
        let y = Measurement::zeros(40, 60);
        let problem = CalibrationProblem::nominal(
            &y,
            &mask,
            10,
            2.0,
            crate::optics::DispersionModel::DispersedMask,
        )
        .unwrap();
        let w = RowWindow {
            first: 20,
            end: 40,
            margin: 0,
        };
        let band = RowBand::cut(&problem, w).unwrap();
        assert_eq!(band.centre_below, 10.0);
        assert_eq!(band.problem(&problem).unwrap().measurement.rows(), 20);
        let seen = band.seen(&psi);
        assert!((seen.dx - (0.3 - 0.5f64.to_radians().sin() * 10.0)).abs() < 1e-12);
        let back = seen.seen_from_rows_below(-band.centre_below);
        assert!((back.dx - psi.dx).abs() < 1e-12 && (back.dy - psi.dy).abs() < 1e-12);
    }
}
