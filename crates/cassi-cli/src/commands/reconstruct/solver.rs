//! `cassi reconstruct` with an iterative solver (GAP-TV, ADMM-TV, PnP-TV):
//! the whole assumed instrument, nominal or from `--calibration`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::bail;
use cassi_core::metrics::Metrics;
use cassi_core::optics::{BandOffsets, BandSpread, DispersionModel};
use cassi_core::recon::Method;
use cassi_core::recon::registry::learned_names;
use cassi_core::solvers::IterationInfo;
use cassi_core::{Instrument, Mismatch};
use cassi_io::CheckedSet;
use serde::Serialize;

use super::args::ReconstructArgs;
use super::outputs::{Outputs, score_against_truth};
use crate::commands::inputs::UncodedMask;
use crate::interrupt;
use crate::report::Reporter;

#[derive(Serialize)]
struct ReconstructionReport {
    measurement: PathBuf,
    mask: PathBuf,
    calibration: Option<PathBuf>,
    model_parameters: Mismatch,
    dispersion_model: DispersionModel,
    /// The calibration's held band offsets, which the model used.
    #[serde(skip_serializing_if = "Option::is_none")]
    band_offsets: Option<BandOffsets>,
    /// The calibration's band spread, which the model used.
    #[serde(skip_serializing_if = "BandSpread::is_point")]
    band_spread: BandSpread,
    method: Method,
    bands: usize,
    iterations: usize,
    stop: cassi_core::solvers::StopReason,
    relative_residual: f64,
    seconds: f64,
    width_fitted: Option<(usize, usize)>,
    /// Metrics of the reconstruction clipped to [0, 1] against the truth.
    metrics: Option<Metrics>,
    metric_definitions: Option<&'static str>,
}

/// `method`: the iterative method `--method` names. `checked`: the
/// outputs, checked against the inputs before any work.
pub fn run(
    args: &ReconstructArgs,
    method: Method,
    reporter: &Reporter,
    checked: &CheckedSet,
) -> anyhow::Result<()> {
    if args.weights.is_some() {
        bail!(
            "--weights is for the learned methods ({}), not --method {}",
            learned_names().collect::<Vec<_>>().join(", "),
            args.method
        );
    }
    let (measurement, mask, bands) = args.input.load(reporter, UncodedMask::Warn)?;
    let file = args.model_parameters(&mask)?;
    let params = file.parameters;
    let model = args.model.or(file.model).unwrap_or_default();
    let instrument = Instrument::with_bands(bands, args.input.stride)?;
    let truth = args.load_truth()?;
    let method = method.with_overrides(args.iterations, args.weight);
    let max_iter = method.iterations();
    let assumed = args.assumed(&mask, bands, &file, model)?;

    let progress = reporter.progress(&format!("{} ", method.name()), max_iter as u64);
    let mut observer = |info: &IterationInfo| {
        progress.set(info.iteration as u64);
        interrupt::control()
    };
    let t0 = Instant::now();
    let recon = reporter.stage(&format!("reconstructing ({})", method.name()), || {
        Ok(method.solve(&measurement, &assumed, &mut observer)?)
    })?;
    drop(progress);
    interrupt::check()?;
    let seconds = t0.elapsed().as_secs_f64();

    let metrics = score_against_truth(truth.as_ref(), &recon.cube)?;
    let report = ReconstructionReport {
        measurement: args.input.measurement.clone(),
        mask: args.input.mask.clone(),
        calibration: args.calibration.clone(),
        model_parameters: params,
        dispersion_model: model,
        band_offsets: file.band_offsets.clone(),
        band_spread: file.band_spread,
        method,
        bands,
        iterations: recon.solution_iterations,
        stop: recon.stop,
        relative_residual: recon.relative_residual,
        seconds,
        width_fitted: recon.width_fitted,
        metrics,
        metric_definitions: metrics.map(|_| cassi_core::metrics::METRIC_DEFINITIONS),
    };
    let summary = format!(
        "wrote {} ({}×{}×{}), {} iterations, residual {:.2e}, {seconds:.2} s",
        args.output.display(),
        bands,
        mask.rows(),
        mask.cols(),
        recon.solution_iterations,
        recon.relative_residual
    );
    let outputs = Outputs {
        path: &args.output,
        cube: &recon.cube,
        wavelengths_nm: &instrument.wavelengths_nm,
        width_fitted: recon.width_fitted,
    };
    outputs.write(reporter, checked, &report, summary, metrics.as_ref())
}
