//! Where each band lands, measured band by band: from a calibrated ψ, the
//! shift δₖ of each band along the dispersion away from a1·k + a2·k² that
//! the scene fit's fine-pass objective prefers (the pose, a1, α, a2 and σ
//! held; the scene re-solved with every step). Why: a prism's dispersion
//! need not follow a low-order polynomial in the band index, and the real
//! snapshots' objective is several times flatter along the dx–a1 ridge
//! than the simulator's, with neighbouring basins a pixel away (stops
//! 52–53); a fitted curvature moved the red end by only ≈ 0.2 px. The
//! shifts measure the dispersion's shape directly.
//!
//! A common shift of every band is what dx does (the code on the detector
//! moves with the band), a shift growing linearly with k what a1 does: the
//! report splits δ into its least-squares line and the shape no straight
//! dispersion has. 28 free shifts lower any objective a little, noise
//! included: whether a shape is the instrument's is read from its
//! agreement between independent parts of the frame (e.g. the top and
//! bottom halves of the rows, [`BandShiftFit::rows`]).

use serde::{Deserialize, Serialize};

use super::CalibrationProblem;
use super::quasi_newton::{LeastSquares, minimise};
use super::scene_fit::{BAND_SHIFT_STEP, FinePass, SceneFit, SceneFitSettings, Solved};
use crate::error::{CassiError, Result};
use crate::params::Mismatch;

/// What the band shifts are fitted on.
#[derive(Debug, Clone, PartialEq)]
pub struct BandShiftFit {
    /// The scene fit whose fine pass gives the objective (the preset's).
    pub settings: SceneFitSettings,
    /// BFGS steps at most (28 shifts take more than the pass's 6
    /// parameters).
    pub max_steps: usize,
    /// The measurement's rows `first..end` scored alone (the rest still
    /// modelled, as [`SceneFit::with_row_window`]); `None`: every row.
    pub rows: Option<(usize, usize)>,
}

impl BandShiftFit {
    /// The fit on `settings`' fine-pass objective, every row, 60 steps.
    pub fn new(settings: SceneFitSettings) -> Self {
        Self {
            settings,
            max_steps: 60,
            rows: None,
        }
    }
}

/// Each band's fitted shift along the dispersion, and its split.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BandShifts {
    /// δₖ: band k lands this many pixels further along the dispersion
    /// than a1·k + a2·k² at the held ψ (a common shift as the mask's move,
    /// [`super::scene_fit::shifted_instrument`]).
    pub along: Vec<f64>,
    /// c and s of the least-squares line c + s·k through δ: a common shift
    /// (what dx absorbs) and a change of slope (what a1 absorbs).
    pub line: [f64; 2],
    /// δₖ − (c + s·k): the part no straight dispersion has.
    pub shape: Vec<f64>,
    /// The fine-pass objective at δ = 0 and at the fitted δ.
    pub score_unshifted: f64,
    pub score_shifted: f64,
    /// Scene solves and Jacobian columns spent.
    pub evaluations: usize,
}

impl BandShifts {
    /// The band positions' RMS departure from their best straight line.
    pub fn shape_rms(&self) -> f64 {
        rms(&self.shape)
    }
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// The shifts of every band of `problem` from `at` (a calibrated ψ) by
/// `how`. Refused without a fine pass in the settings (its objective is
/// the one the shifts are scored on).
pub fn fit_band_shifts(
    problem: &CalibrationProblem<'_>,
    at: &Mismatch,
    how: &BandShiftFit,
) -> Result<BandShifts> {
    let (fine, scene) = objective(problem, at, how)?;
    // no shifts is `at`'s own operator: its cold solve from the first
    // pass's scene, as the fine pass starts
    let start = Shifted {
        solved: fine.solve_cold(at, Some(&scene))?,
        along: vec![0.0; problem.bands()],
    };
    let score_unshifted = start.solved.score;
    let found = minimise(
        &OverShifts {
            fit: &fine,
            base: at,
        },
        start,
        how.max_steps,
    )?;
    let along = found.best.along;
    let (line, shape) = off_line(&along);
    Ok(BandShifts {
        along,
        line,
        shape,
        score_unshifted,
        score_shifted: found.best.solved.score,
        evaluations: 2 + found.evaluations,
    })
}

/// The fine-pass objective (as [`fit_band_shifts`] scores it) with the
/// bands held at each of `tables` (shifts along the dispersion from `at`,
/// one per band; the scene solved afresh for each): whether a shape
/// measured elsewhere (another snapshot of the camera) explains this one.
pub fn band_shift_scores(
    problem: &CalibrationProblem<'_>,
    at: &Mismatch,
    how: &BandShiftFit,
    tables: &[Vec<f64>],
) -> Result<Vec<f64>> {
    let (fine, scene) = objective(problem, at, how)?;
    tables
        .iter()
        .map(|along| {
            let cold = fine.settings().cold_solve;
            Ok(fine
                .solve_band_shifted((at, along), Some(&scene), cold)?
                .score)
        })
        .collect()
}

/// The fine pass's scene fit from `at` (and the first pass's scene on its
/// nodes, where its solves start), on `how`'s rows.
fn objective<'a>(
    problem: &'a CalibrationProblem<'a>,
    at: &Mismatch,
    how: &BandShiftFit,
) -> Result<(SceneFit<'a>, Vec<f32>)> {
    let Some(pass) = how.settings.fine_pass else {
        return Err(CassiError::Meaningless {
            what: "the band shifts' fit".into(),
            reason: "it scores on the scene fit's fine pass, and these settings have none".into(),
        });
    };
    let coarse = SceneFit::new(problem, how.settings.first_pass_only())?;
    let first = coarse.solve_cold(at, None)?;
    // its objective as it was tuned (stop 55): the pass's own warm solves,
    // not an off-grid run's
    let pass = FinePass {
        off_grid_run: None,
        ..pass
    };
    let (mut fine, scene) = pass.scene_fit(problem, how.settings, (&coarse, &first), None)?;
    if let Some((start, end)) = how.rows {
        let rows = problem.measurement.rows();
        if start >= end || end > rows {
            return Err(CassiError::InvalidParameter {
                name: "rows",
                value: end as f64,
                reason: format!("rows {start}..{end} are not a window of the {rows} rows"),
            });
        }
        fine = fine.with_row_window(start, end);
    }
    Ok((fine, scene))
}

/// v's least-squares line [c, s] (c + s·k) and v's departure from it.
fn off_line(v: &[f64]) -> ([f64; 2], Vec<f64>) {
    let line = straight_line(v);
    let shape = v
        .iter()
        .enumerate()
        .map(|(k, d)| d - (line[0] + line[1] * k as f64))
        .collect();
    (line, shape)
}

/// The least-squares [c, s] of c + s·k through v.
fn straight_line(v: &[f64]) -> [f64; 2] {
    let n = v.len() as f64;
    let mean_k = (n - 1.0) / 2.0;
    let mean_v = v.iter().sum::<f64>() / n.max(1.0);
    let (mut skv, mut skk) = (0.0, 0.0);
    for (k, &d) in v.iter().enumerate() {
        let dk = k as f64 - mean_k;
        skv += dk * (d - mean_v);
        skk += dk * dk;
    }
    let s = if skk > 0.0 { skv / skk } else { 0.0 };
    [mean_v - s * mean_k, s]
}

/// A solve at some band shifts.
struct Shifted {
    along: Vec<f64>,
    solved: Solved,
}

/// The fine-pass objective over the band shifts from `base`.
struct OverShifts<'a, 'f> {
    fit: &'a SceneFit<'f>,
    base: &'a Mismatch,
}

impl LeastSquares for OverShifts<'_, '_> {
    type Point = Shifted;
    fn coordinates(&self, at: &Shifted) -> Vec<f64> {
        at.along.clone()
    }
    fn residual<'p>(&self, at: &'p Shifted) -> &'p [f32] {
        &at.solved.residual
    }
    fn score(&self, at: &Shifted) -> f64 {
        at.solved.score
    }
    fn energy(&self) -> f64 {
        self.fit.data_energy()
    }
    fn step(&self, at: &Shifted, step: &[f64]) -> Result<Shifted> {
        let along: Vec<f64> = at.along.iter().zip(step).map(|(a, d)| a + d).collect();
        let solved = self.fit.solve_band_shifted(
            (self.base, &along),
            Some(&at.solved.z),
            self.fit.settings().warm_solve,
        )?;
        Ok(Shifted { along, solved })
    }
    fn jacobian(&self, at: &Shifted) -> Result<Vec<Vec<f32>>> {
        self.fit
            .band_shift_jacobian(&at.solved, self.base, &at.along)
    }
    fn settled(&self, step: &[f64]) -> bool {
        step.iter().all(|d| d.abs() < BAND_SHIFT_STEP / 5.0)
    }
}

#[cfg(test)]
mod tests {
    use super::super::scene_fit::shifted_instrument;
    use super::super::scene_fit::tests::{BANDS, measured, truth};
    use super::*;
    use crate::optics::DispersionModel;

    #[test]
    fn a_straight_line_is_split_off_exactly() {
        let v: Vec<f64> = (0..7).map(|k| 0.3 - 0.02 * k as f64).collect();
        let [c, s] = straight_line(&v);
        assert!(
            (c - 0.3).abs() < 1e-12 && (s + 0.02).abs() < 1e-12,
            "{c} {s}"
        );
    }

    /// A measurement (4× oversampled simulator with blur and noise: not
    /// the fitted operator) of a prism curved by `a2`, the straight ψ on
    /// the curve's best line (its slope in a1, its common shift in the
    /// mask's place: what a straight calibration leaves the shifts to
    /// find) and the curvature's departure from that line.
    fn curved_prism(a2: f64) -> (crate::Measurement, crate::Mask, Mismatch, Vec<f64>) {
        let instrument = Mismatch { a2, ..truth() };
        let (y, mask) = measured(&instrument, true);
        let k2: Vec<f64> = (0..BANDS).map(|k| a2 * (k * k) as f64).collect();
        let (line, departure) = off_line(&k2);
        let straight = Mismatch {
            a1: instrument.a1 + line[1],
            a2: 0.0,
            ..instrument
        };
        let (at, _) = shifted_instrument(&straight, &[line[0]]);
        (y, mask, at, departure)
    }

    fn problem<'a>(y: &'a crate::Measurement, mask: &'a crate::Mask) -> CalibrationProblem<'a> {
        CalibrationProblem::nominal(y, mask, BANDS, 2.0, DispersionModel::DispersedMask).unwrap()
    }

    /// The shifts from a straight calibration of a curved prism follow the
    /// curvature's departure from a straight line; on a straight prism the
    /// shape stays near zero.
    #[test]
    fn the_band_shifts_follow_a_curved_prism() {
        let shapes = |a2: f64| {
            let (y, mask, at, expected) = curved_prism(a2);
            let how = BandShiftFit::new(SceneFitSettings::default());
            let fitted = fit_band_shifts(&problem(&y, &mask), &at, &how).unwrap();
            eprintln!(
                "a2 {a2}: shape {:.3?}\nexpected {:.3?}\nscore {} -> {} ({} evaluations)",
                fitted.shape,
                expected,
                fitted.score_unshifted,
                fitted.score_shifted,
                fitted.evaluations
            );
            assert!(fitted.score_shifted < fitted.score_unshifted);
            (fitted, expected)
        };
        let (curved, expected) = shapes(-0.008);
        let miss: Vec<f64> = curved
            .shape
            .iter()
            .zip(&expected)
            .map(|(a, b)| a - b)
            .collect();
        // the curvature's departure reaches 0.28 px at the ends (RMS 0.15)
        assert!(rms(&expected) > 0.14);
        assert!(rms(&miss) < 0.05, "missed by {:.3?}", miss);
        let (straight, _) = shapes(0.0);
        assert!(straight.shape_rms() < 0.05, "{:.3?}", straight.shape);
    }

    /// A shape held fixed scores the curved prism better than none, and its
    /// opposite worse.
    #[test]
    fn a_known_shape_lowers_the_objective_and_its_opposite_raises_it() {
        let (y, mask, at, shape) = curved_prism(-0.008);
        let opposite: Vec<f64> = shape.iter().map(|v| -v).collect();
        let how = BandShiftFit::new(SceneFitSettings::default());
        let tables = [vec![0.0; BANDS], shape, opposite];
        let s = band_shift_scores(&problem(&y, &mask), &at, &how, &tables).unwrap();
        eprintln!("none {} shape {} opposite {}", s[0], s[1], s[2]);
        assert!(s[1] < 0.9 * s[0] && s[2] > s[0], "{s:?}");
    }

    #[test]
    fn a_fit_without_a_fine_pass_is_refused() {
        let (y, mask) = measured(&truth(), false);
        let how = BandShiftFit::new(SceneFitSettings::default().first_pass_only());
        let e = fit_band_shifts(&problem(&y, &mask), &truth(), &how)
            .unwrap_err()
            .to_string();
        assert!(e.contains("fine pass"), "{e}");
    }
}
