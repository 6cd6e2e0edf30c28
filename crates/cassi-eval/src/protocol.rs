//! The four-scenario protocol for one scene (paper §5), without the
//! reference code's confounds (seed-code notes §9, §12): every scenario runs
//! the same solver with the same settings and the same post-processing
//! (clip to [0, 1]), Scenario I is reported noise-free and noisy, and all of
//! II–IV reconstruct the *same* noisy measurement.
//!
//! - I   Ideal: a perfectly aligned instrument (nominal mask, a1 = stride,
//!   α = 0), reconstructed with the nominal model.
//! - II  Assumed: the mismatched instrument's measurement, nominal model.
//! - III Corrected: the same measurement, the self-calibrated model.
//! - IV  Oracle: the same measurement, the true model. When the instrument
//!   is `subpixel`, its measurement is simulated on a 2× finer grid and
//!   binned ([`cassi_core::optics::simulate_oversampled`]), so the oracle's
//!   operator is not the one that made the data (no inverse crime).
//!
//! Learned methods take what they can of each scenario's model: networks
//! the mask pose, PnP-HSICNN all of it ([`crate::learned`]).

use std::time::Instant;

use anyhow::Context;
use cassi_core::calib::{Calibration, CalibrationProblem, Preset, calibrate};
use cassi_core::metrics::{Metrics, evaluate};
use cassi_core::optics::{DispersionModel, NoiseModel, SimulationSpec, simulate};
use cassi_core::recon::Model;
use cassi_core::solvers::Silent;
use cassi_core::{Cube, Mask, Measurement, Mismatch, Parameter};
use serde::{Deserialize, Serialize};

use crate::method::StudyMethod;

/// What a scene's work reports as it goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneProgress<'a> {
    /// One of the scene's counted steps begins
    /// ([`Study::steps_per_scene`] in all).
    Step(&'a str),
    /// A self-calibration stage ended (not counted): a point where a front
    /// end may stop the work, which a calibration cannot otherwise offer.
    CalibrationStage(&'a str),
}

/// What a study fixes for every scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Study {
    /// The true instrument relative to the nominal one.
    pub mismatch: Mismatch,
    /// How the true instrument disperses; calibration and reconstruction use
    /// the same model family.
    pub instrument: DispersionModel,
    pub noise: NoiseModel,
    pub preset: Preset,
    pub methods: Vec<StudyMethod>,
    /// Nominal dispersion stride, px per band.
    pub stride: f64,
}

impl Study {
    /// How many progress steps `run_scene` reports per scene: simulating,
    /// self-calibrating, then every method in every scenario.
    pub fn steps_per_scene(&self) -> u64 {
        2 + (Scenario::ALL.len() * self.methods.len()) as u64
    }
}

/// One of the protocol's reconstructions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Scenario {
    IdealClean,
    IdealNoisy,
    Assumed,
    Corrected,
    Oracle,
}

impl Scenario {
    pub const ALL: [Scenario; 5] = [
        Self::IdealClean,
        Self::IdealNoisy,
        Self::Assumed,
        Self::Corrected,
        Self::Oracle,
    ];

    /// Short label for tables and figures.
    pub fn label(self) -> &'static str {
        match self {
            Self::IdealClean => "I Ideal (noise-free)",
            Self::IdealNoisy => "I Ideal (noisy)",
            Self::Assumed => "II Assumed",
            Self::Corrected => "III Corrected",
            Self::Oracle => "IV Oracle",
        }
    }
}

/// A reconstruction's scores.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Outcome {
    pub method: String,
    pub scenario: Scenario,
    pub metrics: Metrics,
    pub seconds: f64,
}

/// Estimated − true, per parameter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ParameterErrors(Mismatch);

impl ParameterErrors {
    /// estimate − truth, per parameter.
    pub fn between(estimate: &Mismatch, truth: &Mismatch) -> Self {
        Self::from_fn(|p| p.get(estimate) - p.get(truth))
    }

    /// One value per parameter, from `f`.
    pub fn from_fn(f: impl Fn(Parameter) -> f64) -> Self {
        let mut m = Mismatch::nominal(0.0);
        for p in Parameter::CALIBRATED {
            p.set(&mut m, f(p));
        }
        Self(m)
    }

    /// The value of parameter `p`.
    pub fn get(&self, p: Parameter) -> f64 {
        p.get(&self.0)
    }

    /// `dx +0.012 px  dy −0.004 px  θ +0.002 °  …`, one decimal more than
    /// the parameters' own precision.
    pub fn format_all(&self) -> String {
        Parameter::CALIBRATED
            .iter()
            .map(|&p| {
                format!(
                    "{} {:+.d$} {}",
                    p.name(),
                    self.get(p),
                    p.unit(),
                    d = p.decimals() + 1
                )
            })
            .collect::<Vec<_>>()
            .join("  ")
    }
}

/// Everything the protocol measured on one scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneResult {
    pub scene: String,
    pub truth: Mismatch,
    pub calibration: Calibration,
    pub errors: ParameterErrors,
    pub outcomes: Vec<Outcome>,
    pub seconds: f64,
}

impl SceneResult {
    pub fn outcome(&self, method: &str, scenario: Scenario) -> Option<&Outcome> {
        self.outcomes
            .iter()
            .find(|o| o.method == method && o.scenario == scenario)
    }
}

/// The measurements and the calibration every method shares.
pub struct Prepared {
    pub ideal_clean: Measurement,
    pub ideal_noisy: Measurement,
    pub measurement: Measurement,
    pub calibration: Calibration,
}

/// Simulates the three measurements and self-calibrates.
pub fn prepare(
    scene: &Cube,
    mask: &Mask,
    study: &Study,
    noise_seed: u64,
    progress: &mut dyn FnMut(SceneProgress<'_>),
) -> anyhow::Result<Prepared> {
    let noise = NoiseModel {
        seed: noise_seed,
        ..study.noise
    };
    progress(SceneProgress::Step("simulating"));
    let (ideal_clean, ideal_noisy) = ideal_measurements(scene, mask, study.stride, &noise)?;
    let spec = SimulationSpec {
        mismatch: study.mismatch,
        model: study.instrument,
        noise: Some(noise),
    };
    let measurement = match study.instrument {
        DispersionModel::Rounded => simulate(scene, mask, &spec)?,
        DispersionModel::Subpixel
        | DispersionModel::DispersedMask
        | DispersionModel::CrispCells => {
            cassi_core::optics::simulate_oversampled(scene, mask, &spec, 2)?
        }
    };
    progress(SceneProgress::Step("self-calibrating"));
    let problem = CalibrationProblem::nominal(
        &measurement,
        mask,
        scene.bands(),
        study.stride,
        study.instrument,
    )?;
    let calibration = calibrate(&problem, &study.preset, &mut |stage| {
        progress(SceneProgress::CalibrationStage(&stage.name))
    })?;
    Ok(Prepared {
        ideal_clean,
        ideal_noisy,
        measurement,
        calibration,
    })
}

/// Scenario I's measurements: the aligned instrument (nominal mask, a1 =
/// `stride`, α = 0), noise-free and with `noise`.
pub fn ideal_measurements(
    scene: &Cube,
    mask: &Mask,
    stride: f64,
    noise: &NoiseModel,
) -> anyhow::Result<(Measurement, Measurement)> {
    let ideal = |noise| SimulationSpec {
        mismatch: Mismatch::nominal(stride),
        model: DispersionModel::Rounded,
        noise,
    };
    Ok((
        simulate(scene, mask, &ideal(None))?,
        simulate(scene, mask, &ideal(Some(*noise)))?,
    ))
}

/// Reconstructs one scenario with one method and scores it against `scene`;
/// also returns the (clipped) reconstruction.
pub fn run_scenario(
    scene: &Cube,
    mask: &Mask,
    study: &Study,
    prepared: &Prepared,
    method: &StudyMethod,
    scenario: Scenario,
) -> anyhow::Result<(Outcome, Cube)> {
    let nominal = Mismatch::nominal(study.stride);
    let (y, params, model) = match scenario {
        Scenario::IdealClean => (&prepared.ideal_clean, nominal, DispersionModel::Rounded),
        Scenario::IdealNoisy => (&prepared.ideal_noisy, nominal, DispersionModel::Rounded),
        Scenario::Assumed => (&prepared.measurement, nominal, study.instrument),
        Scenario::Corrected => (
            &prepared.measurement,
            prepared.calibration.reconstruction_parameters(),
            study.instrument,
        ),
        Scenario::Oracle => (&prepared.measurement, study.mismatch, study.instrument),
    };
    // the mismatched scenarios reconstruct in the calibrated model's family:
    // what the calibration held beside ψ (band offsets, band spread) too
    let calibration = &prepared.calibration;
    let (metrics, seconds, cube) = Model::new(mask, scene.bands(), study.stride, params, model)
        .and_then(|m| match scenario {
            Scenario::IdealClean | Scenario::IdealNoisy => Ok(m),
            Scenario::Assumed | Scenario::Corrected | Scenario::Oracle => {
                m.holding(calibration.band_offsets.as_ref(), calibration.band_spread)
            }
        })
        .map_err(anyhow::Error::from)
        .and_then(|assumed| reconstruct_and_score(scene, y, &assumed, method))
        .with_context(|| format!("{} {}", method.name(), scenario.label()))?;
    let outcome = Outcome {
        method: method.name().to_string(),
        scenario,
        metrics,
        seconds,
    };
    Ok((outcome, cube))
}

/// Reconstructs `y` with the assumed instrument `model`, clips to [0, 1]
/// and scores against `scene`: the metrics, the reconstruction's seconds
/// and the clipped cube. Learned methods take what they can of the model
/// ([`crate::learned`]: networks use the mask pose only).
pub fn reconstruct_and_score(
    scene: &Cube,
    y: &Measurement,
    model: &Model,
    method: &StudyMethod,
) -> anyhow::Result<(Metrics, f64, Cube)> {
    let t = Instant::now();
    let cube = match method {
        StudyMethod::Solver(m) => m.solve(y, model, &mut Silent)?.cube,
        StudyMethod::Learned(l) => l.reconstruct(y, model)?,
    };
    let seconds = t.elapsed().as_secs_f64();
    let cube = cube.clipped_to_unit();
    Ok((evaluate(scene, &cube)?, seconds, cube))
}

/// The first method's reconstruction in each scenario, for figures.
pub type Reconstructions = Vec<(Scenario, Cube)>;

/// The whole protocol on one scene. `progress` hears each step and each
/// calibration stage. With
/// `keep`, also returns the first method's reconstructions.
pub fn run_scene(
    name: &str,
    scene: &Cube,
    mask: &Mask,
    study: &Study,
    noise_seed: u64,
    keep: bool,
    progress: &mut dyn FnMut(SceneProgress<'_>),
) -> anyhow::Result<(SceneResult, Reconstructions)> {
    let t = Instant::now();
    let prepared = prepare(scene, mask, study, noise_seed, progress)?;
    run_prepared(name, scene, mask, study, &prepared, t, keep, progress)
}

/// Every method in every scenario on measurements and a calibration already
/// made (`started`: when the scene's work began, for its total time).
#[allow(clippy::too_many_arguments)]
pub fn run_prepared(
    name: &str,
    scene: &Cube,
    mask: &Mask,
    study: &Study,
    prepared: &Prepared,
    started: Instant,
    keep: bool,
    progress: &mut dyn FnMut(SceneProgress<'_>),
) -> anyhow::Result<(SceneResult, Reconstructions)> {
    let mut outcomes = Vec::new();
    let mut kept = Vec::new();
    for (mi, method) in study.methods.iter().enumerate() {
        for scenario in Scenario::ALL {
            progress(SceneProgress::Step(&format!(
                "{} {}",
                method.name(),
                scenario.label()
            )));
            let (outcome, cube) = run_scenario(scene, mask, study, prepared, method, scenario)?;
            outcomes.push(outcome);
            if keep && mi == 0 {
                kept.push((scenario, cube));
            }
        }
    }
    let result = SceneResult {
        scene: name.to_string(),
        truth: study.mismatch,
        errors: ParameterErrors::between(&prepared.calibration.parameters, &study.mismatch),
        calibration: prepared.calibration.clone(),
        outcomes,
        seconds: started.elapsed().as_secs_f64(),
    };
    Ok((result, kept))
}

#[cfg(test)]
mod tests {
    /// A study (and the learned models its methods hold) can be shared
    /// across threads.
    #[test]
    fn studies_can_be_shared_across_threads() {
        fn shareable<T: Send + Sync>() {}
        shareable::<super::Study>();
    }
}
