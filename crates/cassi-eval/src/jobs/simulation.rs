//! A simulated measurement written with its sidecar record: what
//! `cassi simulate` and `cassi demo` make.

use std::path::Path;

use cassi_core::optics::{PhysicalSpec, SimulationSpec, simulate, simulate_physical};
use cassi_core::{Cube, Instrument, Mask, Measurement};
use cassi_io::OutputSet;

use super::{JobObserver, stage};
use crate::records::{MeasurementInfo, SimulationRecord, Source, sidecar_path, write_record};

/// Everything a simulation needs, and where its inputs came from (for the
/// sidecar).
pub struct SimulationInputs {
    pub scene: Cube,
    pub scene_source: Source,
    pub mask: Mask,
    pub mask_source: Source,
    pub instrument: Instrument,
    pub spec: SimulationSpec,
    /// The physical simulator's grid, blur and sensor; `None`: the discrete
    /// operator of `spec.model`.
    pub physical: Option<PhysicalSpec>,
}

impl SimulationInputs {
    /// The snapshot these inputs make (noise as `spec` says).
    pub fn simulate(&self) -> anyhow::Result<Measurement> {
        self.simulate_with(&self.spec)
    }

    /// The same instrument's snapshot without noise.
    pub fn simulate_noise_free(&self) -> anyhow::Result<Measurement> {
        self.simulate_with(&SimulationSpec {
            noise: None,
            ..self.spec
        })
    }

    fn simulate_with(&self, spec: &SimulationSpec) -> anyhow::Result<Measurement> {
        Ok(match &self.physical {
            None => simulate(&self.scene, &self.mask, spec)?,
            Some(physical) => simulate_physical(
                &self.scene,
                &self.mask,
                &self.instrument.wavelengths_nm,
                &spec.mismatch,
                physical,
                spec.noise.as_ref(),
            )?,
        })
    }
}

/// Declares the files [`simulate_and_record`] writes for `output` (the
/// measurement, its sidecar and, with `preview`, its PNG); `flag` names the
/// output as the user gave it.
pub fn declare_outputs(set: &mut OutputSet, flag: &str, output: &Path, preview: bool) {
    set.output(flag, output).output(
        format!("the sidecar ({flag} with .json)"),
        sidecar_path(output),
    );
    if preview {
        set.output(
            format!("the preview ({flag} with .png)"),
            output.with_extension("png"),
        );
    }
}

/// Simulates the measurement and writes it to `output` with its sidecar
/// (and a PNG preview with `preview`).
pub fn simulate_and_record(
    inputs: &SimulationInputs,
    output: &Path,
    preview: bool,
    observer: &mut dyn JobObserver,
) -> anyhow::Result<(Measurement, SimulationRecord)> {
    let measurement = stage(observer, "simulating the measurement", |_| {
        inputs.simulate()
    })?;
    observer.checkpoint()?;
    let (min, max) = measurement.min_max();
    let record = SimulationRecord {
        cassi_version: env!("CARGO_PKG_VERSION").to_string(),
        scene: inputs.scene_source.clone(),
        mask: inputs.mask_source.clone(),
        instrument: inputs.instrument.clone(),
        simulation: inputs.spec,
        physical: inputs.physical,
        measurement: MeasurementInfo {
            path: output.to_path_buf(),
            shape: [measurement.rows(), measurement.cols()],
            min,
            max,
        },
    };
    stage(observer, "writing the measurement", |_| {
        cassi_io::save_frame(output, &measurement, "measurement")?;
        write_record(sidecar_path(output), &record)?;
        if preview {
            cassi_io::write_frame_png16(output.with_extension("png"), &measurement, None)?;
        }
        Ok(())
    })?;
    Ok((measurement, record))
}
