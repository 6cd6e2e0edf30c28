//! The blur pass (opt-in, measured; see [`BlurPass`]): σ refitted last,
//! the geometry held, on the crisp-cell model with a coarse scene that
//! carries GAP-TV's texture. Why: the first pass fits σ on an 8-px smooth
//! scene, which reads it high by the texture it cannot hold (aligned
//! instruments at σ 0.7: +0.05 … +0.07 px on the held-out scenes), while
//! the dispersed-mask model reads it low at fractional mask phases; on
//! the tuning half the crisp-cell model with the detail pass refitting all
//! six on GAP-TV's detail maps put every aligned σ within 0.05 px
//! (`calibrate_physical_tuning_crisp_cells_detail_all_gap_tv50.json`) but
//! let dy and α slide. This pass takes σ alone from that fit and keeps the
//! default's geometry.
//!
//! Tuning half, 45 cases (`calibrate_physical_tuning_blur_pass.json`; the
//! σ before it is the run's previous stage, the default's answer): random
//! poses σ RMSE 0.052 → 0.041 px, within 19 → 22 of 30, all six 12 → 16;
//! aligned σ RMSE 0.038 → 0.030, mean +0.018 → +0.009, but beads at σ 0.3
//! +0.045 → +0.056 (all six 13 → 12 of 15): 25 → 28 of 45. With 20
//! GAP-TV iterations (`…_tuning_blur_pass_gap20.json`) alike (28 of 45,
//! σ RMSE random 0.040, aligned 0.031) and the stage 2.85 s instead of
//! 3.52 s (medians in runs that overlapped: not timing figures): the
//! crisp-cell model's cold solves, not GAP-TV, are most of its cost. Held
//! out, fresh round 12, checked once
//! (`calibrate_physical_held_out_round12_blur_pass.json`): aligned σ RMSE
//! 0.028 → 0.015 px, all six 14 → 15 of 15; random σ RMSE 0.032 → 0.027,
//! all six 7 → 7 of 20. Opt-in, not the default: the timing bench, run
//! alone (`calibrate_physical_held_out_timing_blur_pass.json`), puts the
//! stage at 3.07 s (median) of 15.5 s per case — a fifth of a
//! calibration, which would take the 10-node default's 4.53 s median to
//! about 5.6 s, over the 5 s.

use serde::{Deserialize, Serialize};

use super::detail_pass::{DetailPass, DetailSource};
use super::scene_fit::{SceneFit, SceneFitSettings, fit_scene};
use super::score::{CalibrationProblem, ProxyParams};
use crate::error::{CassiError, Result};
use crate::optics::DispersionModel;
use crate::params::{Mismatch, Parameter};

/// Settings of the blur pass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BlurPass {
    /// The model σ is refitted in.
    pub model: DispersionModel,
    /// GAP-TV's iterations for the detail maps' scene.
    pub gap_iterations: usize,
}

impl Default for BlurPass {
    fn default() -> Self {
        Self {
            model: DispersionModel::CrispCells,
            gap_iterations: 50,
        }
    }
}

/// What the pass found: σ and the scene fit's score there.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BlurRefit {
    pub blur_sigma_px: f64,
    /// ‖r‖² / ‖H y‖² on the pass's own objective (not the first pass's).
    pub score: f64,
    pub evaluations: usize,
}

impl BlurPass {
    /// Its settings, named when out of range (a settings file's, say).
    pub(crate) fn check(&self) -> Result<()> {
        if self.gap_iterations == 0 {
            return Err(CassiError::InvalidParameter {
                name: "blur_pass.gap_iterations",
                value: 0.0,
                reason: "GAP-TV's iterations for the blur pass's texture: 1 or more".into(),
            });
        }
        Ok(())
    }

    /// σ refitted at `at` (every other parameter held): GAP-TV's scene at
    /// `at` gives the detail maps ([`DetailPass`]'s defaults otherwise),
    /// the first pass's coarse scene times them is solved afresh in
    /// [`Self::model`].
    pub(crate) fn refit(
        &self,
        problem: &CalibrationProblem<'_>,
        first_pass: &SceneFitSettings,
        proxy: &ProxyParams,
        at: &Mismatch,
    ) -> Result<BlurRefit> {
        problem.check_cancelled()?;
        self.check()?;
        let maps = DetailPass {
            source: DetailSource::GapTv {
                iterations: self.gap_iterations,
            },
            ..DetailPass::default()
        };
        let detail = maps.detail_map(problem, at, proxy)?;
        let refitted = problem.with_model(self.model);
        let fit = SceneFit::new(&refitted, *first_pass)?.with_detail(detail);
        let found = fit_scene(&fit, at, &[Parameter::BlurSigmaPx])?;
        Ok(BlurRefit {
            blur_sigma_px: found.best.psi.blur_sigma_px.abs(),
            score: found.best.score,
            evaluations: found.evaluations,
        })
    }
}
