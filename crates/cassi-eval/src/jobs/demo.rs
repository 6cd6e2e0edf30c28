//! The demo (`cassi demo`): the paper's mismatch on the embedded synthetic
//! scene, with no input files. By default the snapshot comes from the
//! physical simulator (4× oversampled, crisp mask squares, continuous
//! dispersion, optical blur, a fixed sensor crop), which no operator the
//! calibration fits can reproduce; a model's own operator can make it
//! instead (an inverse crime, kept for comparison). Then self-calibration,
//! GAP-TV in the protocol's scenarios, and the study's report.

use std::path::{Path, PathBuf};

use cassi_core::calib::{
    Calibration, CalibrationProblem, DefaultPreset, Preset, calibrate_default,
};
use cassi_core::color::pseudo_rgb;
use cassi_core::optics::{BandSpread, DispersionModel, NoiseModel, PhysicalSpec, SimulationSpec};
use cassi_core::recon::Method;
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Instrument, Measurement, Mismatch};
use cassi_io::OutputSet;

use super::simulation::{SimulationInputs, simulate_and_record};
use super::{JobObserver, stage};
use crate::protocol::{Prepared, Scenario, SceneResult, Study, ideal_measurements, run_prepared};
use crate::records::{SimulationRecord, Source, write_record};
use crate::report::{Setup, write_all};
use crate::study_figures::write_qualitative;
use crate::summary::summarize;
use crate::sweep_rows::Sweeps;

/// What makes the demo's snapshot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DemoInstrument {
    /// The physical simulator: 4× oversampled, blur σ 0.5 px, each band's
    /// light spread over its width, fixed sensor; calibrated and
    /// reconstructed with the dispersed-mask model and that spread.
    Physical,
    /// The rounded model's own operator (an inverse crime).
    Rounded,
    /// The subpixel model's own operator (an inverse crime).
    Subpixel,
}

impl DemoInstrument {
    pub const ALL: [DemoInstrument; 3] = [Self::Physical, Self::Rounded, Self::Subpixel];

    pub fn name(self) -> &'static str {
        match self {
            Self::Physical => "physical",
            Self::Rounded => "rounded",
            Self::Subpixel => "subpixel",
        }
    }

    /// The instrument called `name`, or an error listing the names.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|i| i.name() == name)
            .ok_or_else(|| {
                let names: Vec<_> = Self::ALL.iter().map(|i| i.name()).collect();
                format!("'{name}': expected one of {}", names.join(", "))
            })
    }

    /// The model family that calibrates and reconstructs the snapshot.
    pub fn model(self) -> DispersionModel {
        match self {
            // the physical instrument is calibrated with the model we
            // recommend for real cameras
            Self::Physical => DispersionModel::DispersedMask,
            Self::Subpixel => DispersionModel::Subpixel,
            Self::Rounded => DispersionModel::Rounded,
        }
    }
}

/// The scene's rows and columns.
pub const SIZE: usize = 256;
/// The random mask's seed.
pub const MASK_SEED: u64 = 1;
/// The physical instrument's grid and blur: a blur within the range the
/// calibration benchmark covers (0–0.8 px).
const OVERSAMPLE: usize = 4;
const BLUR_SIGMA_PX: f64 = 0.5;

/// One demo run.
pub struct DemoPlan {
    /// The folder of the demo's files (created if missing).
    pub out: PathBuf,
    /// The scene's seed.
    pub seed: u64,
    pub instrument: DemoInstrument,
}

/// What the demo found (its files are in the plan's `out`).
pub struct DemoOutcome {
    /// How the snapshot was made (the sidecar written beside it).
    pub record: SimulationRecord,
    /// The noisy snapshot's SNR against the noise-free one, dB.
    pub snr_db: f64,
    pub calibration: Calibration,
    /// The reconstruction method of the scenarios.
    pub method: Method,
    /// The scenarios' scores.
    pub result: SceneResult,
}

impl DemoPlan {
    /// The physical simulator's settings (`None` for a model's operator):
    /// the sensor cropped to the nominal design's width (mask + 27 ×
    /// stride), as a real camera's is.
    pub fn physical(&self) -> Option<PhysicalSpec> {
        let instrument = Instrument::default();
        (self.instrument == DemoInstrument::Physical).then(|| PhysicalSpec {
            oversample: OVERSAMPLE,
            blur_sigma_px: BLUR_SIGMA_PX,
            detector: Some((
                SIZE,
                SIZE + ((instrument.bands - 1) as f64 * instrument.stride).round() as usize,
            )),
            // a camera's spectrum is continuous: each band's light lands
            // across its spacing
            band_spread: BandSpread::Uniform,
            ..PhysicalSpec::default()
        })
    }
}

/// The report file of a demo into `out`.
pub fn report_path(out: &Path) -> PathBuf {
    out.join("report.md")
}

/// Runs the demo: every file goes into the plan's folder, and all of them
/// are replaced together at the end (or none, when anything fails or the
/// observer stops the job).
pub fn run_demo(plan: &DemoPlan, observer: &mut dyn JobObserver) -> anyhow::Result<DemoOutcome> {
    let out = &plan.out;
    let checked = OutputSet::new().output_dir("--out", out).check()?;
    let staging = checked.begin()?;
    let instrument = Instrument::default();
    let scene = stage(observer, "generating the synthetic scene", |_| {
        Ok(synthetic_scene(&SceneSpec {
            rows: SIZE,
            cols: SIZE,
            wavelengths_nm: instrument.wavelengths_nm.clone(),
            seed: plan.seed,
        })?)
    })?;
    let mask = random_binary_mask(SIZE, SIZE, 0.5, MASK_SEED)?;
    let model = plan.instrument.model();
    let physical = plan.physical();
    let spec = SimulationSpec {
        mismatch: Mismatch {
            blur_sigma_px: physical.map_or(0.0, |p| p.blur_sigma_px),
            ..Mismatch::paper()
        },
        model,
        noise: Some(NoiseModel::default()),
    };
    let inputs = SimulationInputs {
        scene,
        scene_source: Source::Synthetic {
            seed: plan.seed,
            rows: SIZE,
            cols: SIZE,
            bands: instrument.bands,
        },
        mask,
        mask_source: Source::Random {
            seed: MASK_SEED,
            open_fraction: 0.5,
            rows: SIZE,
            cols: SIZE,
        },
        instrument,
        spec,
        physical,
    };
    let (measurement, record) =
        simulate_and_record(&inputs, &out.join("measurement.npy"), true, observer)?;
    stage(observer, "writing previews", |_| {
        cassi_io::save_cube(out.join("scene.npy"), &inputs.scene, "scene")?;
        cassi_io::save_frame(out.join("mask.npy"), &inputs.mask, "mask")?;
        cassi_io::write_frame_png16(out.join("mask.png"), &inputs.mask, Some(1.0))?;
        let rgb = pseudo_rgb(&inputs.scene, &inputs.instrument.wavelengths_nm)?;
        cassi_io::write_rgb_png(out.join("scene_rgb.png"), &rgb)?;
        Ok(())
    })?;
    let snr_db = snr_db(&inputs, &measurement)?;

    // Self-calibration from the measurement and the nominal mask alone, in
    // the model `cassi calibrate` fits by default (the band spread too).
    let preset = DefaultPreset::default();
    let problem = CalibrationProblem::nominal(
        &measurement,
        &inputs.mask,
        inputs.instrument.bands,
        inputs.instrument.stride,
        model,
    )?
    .with_band_spread(Preset::Default(preset).default_band_spread(model));
    let calibration = stage(observer, "self-calibrating (default preset)", |o| {
        Ok(calibrate_default(&problem, &preset, &mut |_| {
            o.stop_point()
        })?)
    })?;
    write_record(out.join("calibration.json"), &calibration)?;

    // The protocol's scenarios on this scene, with the measurement and
    // calibration above; then the study's report.
    let method = Method::by_name("gap-tv")?;
    let study = Study {
        mismatch: spec.mismatch,
        instrument: model,
        noise: NoiseModel::default(),
        preset: Preset::Default(preset),
        methods: vec![method.into()],
        stride: inputs.instrument.stride,
    };
    let (ideal_clean, ideal_noisy) = ideal_measurements(
        &inputs.scene,
        &inputs.mask,
        inputs.instrument.stride,
        &NoiseModel::default(),
    )?;
    let prepared = Prepared {
        ideal_clean,
        ideal_noisy,
        measurement,
        calibration: calibration.clone(),
    };
    let (mut result, kept) = stage(observer, "GAP-TV in the five scenario variants", |o| {
        run_prepared(
            &format!("synthetic_{}", plan.seed),
            &inputs.scene,
            &inputs.mask,
            &study,
            &prepared,
            std::time::Instant::now(),
            true,
            &mut |_| o.stop_point(),
        )
    })?;
    // the scene's time includes the calibration made above
    result.seconds += calibration.seconds;
    for (scenario, cube) in &kept {
        let rgb = pseudo_rgb(cube, &inputs.instrument.wavelengths_nm)?;
        let file = format!("recon_{}_rgb.png", scenario_file(*scenario));
        cassi_io::write_rgb_png(out.join(file), &rgb)?;
    }
    stage(observer, "writing the report", |_| {
        write_qualitative(out, &result.scene, method.name(), &inputs.scene, &kept)?;
        let results = [result.clone()];
        let summary = summarize(&results);
        write_all(
            out,
            &Setup {
                scenes: &format!("embedded synthetic scene (seed {})", plan.seed),
                mask: &format!("random binary, 50 % open (seed {MASK_SEED})"),
            },
            &study,
            &results,
            &summary,
            &Sweeps::default(),
        )
    })?;
    observer.checkpoint()?;
    staging.commit()?;
    Ok(DemoOutcome {
        record,
        snr_db,
        calibration,
        method,
        result,
    })
}

/// How much the noise costs: the SNR of the noisy snapshot against the same
/// instrument's noise-free one.
fn snr_db(inputs: &SimulationInputs, noisy: &Measurement) -> anyhow::Result<f64> {
    let clean = inputs.simulate_noise_free()?;
    let (signal, error) = clean
        .as_slice()
        .iter()
        .zip(noisy.as_slice())
        .fold((0.0f64, 0.0f64), |(s, e), (&c, &n)| {
            (s + (c as f64).powi(2), e + (n as f64 - c as f64).powi(2))
        });
    Ok(10.0 * (signal / error.max(f64::MIN_POSITIVE)).log10())
}

fn scenario_file(s: Scenario) -> &'static str {
    match s {
        Scenario::IdealClean => "ideal_noise_free",
        Scenario::IdealNoisy => "ideal",
        Scenario::Assumed => "assumed",
        Scenario::Corrected => "corrected",
        Scenario::Oracle => "oracle",
    }
}
