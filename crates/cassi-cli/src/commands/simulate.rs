//! `cassi simulate`: scene + mask + mismatch + noise → measurement + sidecar.

use std::path::{Path, PathBuf};

use anyhow::Context;
use cassi_core::limits::check_elements;
use cassi_core::optics::{
    MaskCode, SimulationSpec, mask_code, simulate, validate_mismatch_for_mask,
};
use cassi_core::{Cube, Instrument, Mask, Measurement};
use cassi_io::OutputSet;
use clap::Args;

use super::inputs::{
    InstrumentArgs, MaskArgs, MismatchArgs, NoiseArgs, SceneArgs, load_mask, load_scene,
};
use crate::interrupt;
use crate::report::Reporter;
use crate::sidecar::{MeasurementInfo, SimulationRecord, Source, sidecar_path};

#[derive(Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub mask: MaskArgs,
    #[command(flatten)]
    pub instrument: InstrumentArgs,
    #[command(flatten)]
    pub mismatch: MismatchArgs,
    #[command(flatten)]
    pub noise: NoiseArgs,
    /// Output measurement (.npy, .npz or .mat); a JSON sidecar goes beside it.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Also write a 16-bit PNG preview of the measurement beside it.
    #[arg(long)]
    pub preview: bool,
}

/// The inputs of one simulation, already loaded.
pub struct SimulationInputs {
    pub scene: Cube,
    pub scene_source: Source,
    pub mask: Mask,
    pub mask_source: Source,
    pub instrument: Instrument,
    pub spec: SimulationSpec,
}

/// Simulates and writes the measurement, its sidecar and (optionally) a PNG
/// preview. The files go through the caller's output set: call it between
/// [`cassi_io::CheckedSet::begin`] and the commit, with the paths declared
/// by [`declare_outputs`].
pub fn simulate_and_write(
    inputs: &SimulationInputs,
    output: &Path,
    preview: bool,
    reporter: &Reporter,
) -> anyhow::Result<(Measurement, SimulationRecord)> {
    let measurement = reporter.stage("simulating the measurement", || {
        Ok(simulate(&inputs.scene, &inputs.mask, &inputs.spec)?)
    })?;
    interrupt::check()?;
    let (min, max) = measurement.min_max();
    let record = SimulationRecord {
        cassi_version: env!("CARGO_PKG_VERSION").to_string(),
        scene: inputs.scene_source.clone(),
        mask: inputs.mask_source.clone(),
        instrument: inputs.instrument.clone(),
        simulation: inputs.spec,
        measurement: MeasurementInfo {
            path: output.to_path_buf(),
            shape: [measurement.rows(), measurement.cols()],
            min,
            max,
        },
    };
    let text = serde_json::to_string_pretty(&record).context("serialising the sidecar")? + "\n";
    reporter.stage("writing the measurement", || {
        cassi_io::save_frame(output, &measurement, "measurement")?;
        cassi_io::write_atomic(sidecar_path(output), text.as_bytes())?;
        if preview {
            cassi_io::write_frame_png16(output.with_extension("png"), &measurement, None)?;
        }
        Ok(())
    })?;
    Ok((measurement, record))
}

/// The files [`simulate_and_write`] writes for `-o output`.
pub fn declare_outputs(set: &mut OutputSet, output: &Path, preview: bool) {
    set.output("-o", output)
        .output("the sidecar (-o with .json)", sidecar_path(output));
    if preview {
        set.output("the preview (-o with .png)", output.with_extension("png"));
    }
}

/// Refuses an output name cassi cannot write (by its extension).
pub fn check_output(output: &Path) -> anyhow::Result<()> {
    Ok(cassi_io::check_output_format(output)?)
}

pub fn run(args: &SimulateArgs, reporter: &Reporter) -> anyhow::Result<()> {
    check_output(&args.output)?;
    // every file read and written, compared before any work
    let mut set = OutputSet::new();
    if let Some(p) = &args.scene.scene {
        set.input("--scene", p);
    }
    if let Some(p) = &args.mask.mask {
        set.input("--mask", p);
    }
    declare_outputs(&mut set, &args.output, args.preview);
    let checked = set.check()?;
    // Parameters first: a typo should not cost a scene load.
    Instrument::with_bands(1, args.instrument.stride).context("--stride")?;
    let spec = SimulationSpec {
        mismatch: args.mismatch.mismatch(args.instrument.stride)?,
        model: args.mismatch.model,
        noise: args.noise.noise()?,
    };
    let (scene, scene_source) = reporter.stage("loading the scene", || load_scene(&args.scene))?;
    let (mask, mask_source) = load_mask(&args.mask, scene.rows(), scene.cols())?;
    let mask_what = match &args.mask.mask {
        Some(p) => format!("mask {}", p.display()),
        None => "the random mask".to_string(),
    };
    if let MaskCode::Uniform(v) = mask_code(&mask, &mask_what)? {
        reporter.warn(&format!(
            "{mask_what}: every pixel transmits {v}: the measurement will hold no code"
        ));
    }
    let (lo, hi) = scene.min_max();
    if lo < 0.0 || hi > 1.0 {
        reporter.warn(&format!(
            "the scene's values span [{lo}, {hi}]; cassi scenes are reflectances in [0, 1] \
             (the measurement is scaled to --photon-peak all the same, but metrics against \
             this scene assume [0, 1])"
        ));
    }
    validate_mismatch_for_mask(&spec.mismatch, mask.rows(), mask.cols())
        .context("mismatch parameters")?;
    let instrument = Instrument::with_bands(scene.bands(), args.instrument.stride)?;
    // the detector: the mask's rows, its columns plus the dispersion's reach
    let reach = (scene.bands() - 1) as f64 * spec.mismatch.a1;
    check_elements(
        "the measurement",
        &[mask.rows(), mask.cols() + reach.ceil() as usize + 1],
        &format!("{} bands at a1 {}", scene.bands(), spec.mismatch.a1),
    )?;
    let inputs = SimulationInputs {
        scene,
        scene_source,
        mask,
        mask_source,
        instrument,
        spec,
    };
    let staging = checked.begin()?;
    let (measurement, record) = simulate_and_write(&inputs, &args.output, args.preview, reporter)?;
    interrupt::check()?;
    staging.commit()?;
    reporter.say(&format!(
        "wrote {} ({}×{}) and {}",
        args.output.display(),
        measurement.rows(),
        measurement.cols(),
        sidecar_path(&args.output).display()
    ));
    reporter.emit(&serde_json::to_value(&record)?);
    Ok(())
}
