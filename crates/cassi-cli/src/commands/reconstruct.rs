//! `cassi reconstruct`: measurement + mask (+ calibration) → cube, preview,
//! and metrics against a truth cube when one is given.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use cassi_core::color::pseudo_rgb;
use cassi_core::metrics::{Metrics, evaluate};
use cassi_core::optics::{DispersionModel, validate_mismatch_for_mask};
use cassi_core::recon::{METHOD_NAMES, Method, reconstruct};
use cassi_core::solvers::IterationInfo;
use cassi_core::{Instrument, Mismatch, Parameter};
use cassi_io::{CheckedSet, OutputSet};
use clap::Args;
use serde::Serialize;

use super::inputs::{LayoutArg, MeasurementArgs, UncodedMask, parse_iterations, parse_weight};
use super::net_reconstruct::{self, NET_METHOD_NAMES};
use super::simulate::check_output;
use crate::interrupt;
use crate::report::Reporter;

#[derive(Args)]
pub struct ReconstructArgs {
    #[command(flatten)]
    pub input: MeasurementArgs,
    /// A calibration JSON (from `cassi calibrate`) or a simulation sidecar
    /// (its true parameters: the oracle model). Without it: the nominal model.
    /// Networks (mst-s, mst-l, hdnet) use its mask pose (dx, dy, θ) only.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Reconstruction method: an iterative solver, or a pretrained network
    /// (mst-s, mst-l, hdnet) or PnP with a learned denoiser (pnp-hsicnn); these
    /// need --weights and a build with `--features nets`.
    #[arg(long, default_value = "gap-tv", value_parser = method_names())]
    pub method: String,
    /// Weights for --method mst-s / mst-l / hdnet / pnp-hsicnn (the HSI-SDeCNN
    /// denoiser): a PyTorch state-dict .pth or a .safetensors file.
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Override the method's iteration count.
    #[arg(long, value_parser = parse_iterations)]
    pub iterations: Option<usize>,
    /// Override the method's denoiser strength (TV weight), constant.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_weight)]
    pub weight: Option<f32>,
    /// Dispersion model assumed for reconstruction (a calibration may set it).
    #[arg(long)]
    pub model: Option<DispersionModel>,
    /// Output cube (.npy, .npz or .mat); a pseudo-RGB .png and a .json report go beside it.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Ground-truth cube, to report PSNR / SSIM / SAM.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    #[arg(long)]
    pub truth_var: Option<String>,
    /// Axis order of the truth cube.
    #[arg(long, value_enum, default_value = "auto")]
    pub layout: LayoutArg,
}

/// Solver and network method names, for `--method`.
fn method_names() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(METHOD_NAMES.iter().chain(&NET_METHOD_NAMES))
}

/// The model parameters and dispersion model a calibration or sidecar file
/// gives: a calibration's "parameters" (+ "model") or a sidecar's
/// "simulation" → "mismatch" (+ "model"), each an object with exactly the
/// named fields dx, dy, theta_deg, a1, alpha_deg (never read by position),
/// every value a number in range.
pub fn read_model_file(path: &Path) -> anyhow::Result<(Mismatch, Option<DispersionModel>)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not valid JSON", path.display()))?;
    let (params, model, field) = if let Some(p) = v.get("parameters") {
        (p, v.get("model"), "\"parameters\"")
    } else if let Some(sim) = v.get("simulation") {
        (
            sim.get("mismatch").unwrap_or(&serde_json::Value::Null),
            sim.get("model"),
            "\"simulation\".\"mismatch\"",
        )
    } else {
        bail!(
            "{}: no \"parameters\" (calibration) or \"simulation\" (sidecar) object",
            path.display()
        );
    };
    let m = named_mismatch(params).with_context(|| format!("{}: {field}", path.display()))?;
    m.validate()
        .with_context(|| format!("{}: {field}", path.display()))?;
    let model = model
        .map(|m| serde_json::from_value(m.clone()))
        .transpose()
        .with_context(|| format!("{}: \"model\"", path.display()))?;
    Ok((m, model))
}

/// The mismatch from a JSON object with exactly the parameters' named
/// fields (those [`Parameter::optional_in_files`] may be absent).
fn named_mismatch(value: &serde_json::Value) -> anyhow::Result<Mismatch> {
    let names = Parameter::ALL.map(|p| p.key()).join(", ");
    let Some(object) = value.as_object() else {
        bail!(
            "must be an object with the named fields {names} (got {})",
            json_kind(value)
        );
    };
    let unknown: Vec<&str> = object
        .keys()
        .map(String::as_str)
        .filter(|k| !Parameter::ALL.iter().any(|p| p.key() == *k))
        .collect();
    if !unknown.is_empty() {
        bail!(
            "unknown field(s) {}; the parameters are {names}",
            unknown.join(", ")
        );
    }
    let mut m = Mismatch::nominal(0.0);
    for p in Parameter::ALL {
        let name = p.key();
        let v = match object.get(name) {
            Some(serde_json::Value::Number(n)) => n.as_f64().unwrap_or(f64::NAN),
            Some(other) => bail!("{name} must be a number, got {}", json_kind(other)),
            None if p.optional_in_files() => p.get(&Mismatch::nominal(0.0)),
            None => bail!("{name} is missing (the parameters are {names})"),
        };
        p.set(&mut m, v);
    }
    Ok(m)
}

fn json_kind(value: &serde_json::Value) -> &'static str {
    match value {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

#[derive(Serialize)]
struct ReconstructionReport {
    measurement: PathBuf,
    mask: PathBuf,
    calibration: Option<PathBuf>,
    model_parameters: Mismatch,
    dispersion_model: DispersionModel,
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

pub fn run(args: &ReconstructArgs, reporter: &Reporter) -> anyhow::Result<()> {
    let checked = args.check_files()?;
    if NET_METHOD_NAMES.contains(&args.method.as_str()) {
        return net_reconstruct::run(args, reporter, &checked);
    }
    if args.weights.is_some() {
        bail!(
            "--weights is for the learned methods ({}), not --method {}",
            NET_METHOD_NAMES.join(", "),
            args.method
        );
    }
    let (measurement, mask, bands) = args.input.load(reporter, UncodedMask::Warn)?;
    let (params, file_model) = args.model_parameters(&mask)?;
    let model = args.model.or(file_model).unwrap_or_default();
    let instrument = Instrument::with_bands(bands, args.input.stride)?;
    let truth = args.load_truth()?;
    let method = Method::by_name(&args.method)?.with_overrides(args.iterations, args.weight);
    let max_iter = match method {
        Method::GapTv { gap, .. } | Method::PnpTv { gap, .. } => gap.iterations,
        Method::AdmmTv { admm, .. } => admm.iterations,
    };

    let progress = reporter.progress(&format!("{} ", method.name()), max_iter as u64);
    let mut observer = |info: &IterationInfo| {
        progress.set(info.iteration as u64);
        interrupt::control()
    };
    let t0 = Instant::now();
    let recon = reporter.stage(&format!("reconstructing ({})", method.name()), || {
        Ok(reconstruct(
            &measurement,
            &mask,
            bands,
            &params,
            model,
            &method,
            &mut observer,
        )?)
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
    outputs.write(reporter, &checked, &report, summary, metrics.as_ref())
}

impl ReconstructArgs {
    /// Checks every output (the cube, its .png and .json) against every
    /// input before any work; see [`cassi_io::OutputSet`].
    pub(crate) fn check_files(&self) -> anyhow::Result<CheckedSet> {
        check_output(&self.output)?;
        let mut set = OutputSet::new();
        self.input.declare_inputs(&mut set);
        for (flag, path) in [
            ("--calibration", &self.calibration),
            ("--truth", &self.truth),
            ("--weights", &self.weights),
        ] {
            if let Some(p) = path {
                set.input(flag, p);
            }
        }
        set.output("-o", &self.output)
            .output(
                "the preview (-o with .png)",
                self.output.with_extension("png"),
            )
            .output(
                "the report (-o with .json)",
                self.output.with_extension("json"),
            );
        Ok(set.check()?)
    }

    /// The model's parameters (and the dispersion model a file names):
    /// `--calibration`'s, or the nominal instrument's.
    /// `mask` is the nominal mask the parameters move: a shift beyond it is
    /// refused, naming the file.
    pub(crate) fn model_parameters(
        &self,
        mask: &cassi_core::Mask,
    ) -> anyhow::Result<(Mismatch, Option<DispersionModel>)> {
        match &self.calibration {
            Some(path) => {
                let (m, model) = read_model_file(path)?;
                validate_mismatch_for_mask(&m, mask.rows(), mask.cols())
                    .with_context(|| format!("{}", path.display()))?;
                Ok((m, model))
            }
            None => Ok((Mismatch::nominal(self.input.stride), None)),
        }
    }

    /// The `--truth` cube, if given.
    pub(crate) fn load_truth(&self) -> anyhow::Result<Option<cassi_core::Cube>> {
        self.truth
            .as_ref()
            .map(|path| {
                cassi_io::load_cube(path, self.truth_var.as_deref(), self.layout.into())
                    .map_err(Into::into)
            })
            .transpose()
    }
}

/// PSNR/SSIM/SAM of the clipped estimate against `--truth`, if given.
pub(crate) fn score_against_truth(
    truth: Option<&cassi_core::Cube>,
    cube: &cassi_core::Cube,
) -> anyhow::Result<Option<Metrics>> {
    truth
        .map(|t| evaluate(t, &cube.clipped_to_unit()).with_context(|| "comparing with --truth"))
        .transpose()
}

/// What every reconstruction writes: the cube, its pseudo-RGB preview, the
/// JSON report beside them, and a summary line (+ metrics) on the terminal.
pub(crate) struct Outputs<'a> {
    pub path: &'a Path,
    pub cube: &'a cassi_core::Cube,
    pub wavelengths_nm: &'a [f64],
    pub width_fitted: Option<(usize, usize)>,
}

impl Outputs<'_> {
    /// Writes the three files as one set ([`ReconstructArgs::check_files`]):
    /// all of them, or — when anything fails, the cube is not finite, or a
    /// signal came — none, the previous ones left as they were.
    pub(crate) fn write(
        &self,
        reporter: &Reporter,
        checked: &CheckedSet,
        report: &impl Serialize,
        mut summary: String,
        metrics: Option<&Metrics>,
    ) -> anyhow::Result<()> {
        self.cube
            .check_finite("the reconstruction")
            .with_context(|| {
                format!(
                    "nothing was written to {} (try fewer iterations or another --weight)",
                    self.path.display()
                )
            })?;
        let rgb = pseudo_rgb(self.cube, self.wavelengths_nm).with_context(|| {
            format!(
                "the preview of {}; nothing was written",
                self.path.display()
            )
        })?;
        let text = serde_json::to_string_pretty(report)? + "\n";
        reporter.stage("writing the cube and preview", || {
            let staging = checked.begin()?;
            cassi_io::save_cube(self.path, self.cube, "cube")?;
            cassi_io::write_rgb_png(self.path.with_extension("png"), &rgb)?;
            cassi_io::write_atomic(self.path.with_extension("json"), text.as_bytes())?;
            interrupt::check()?;
            staging.commit()?;
            Ok(())
        })?;
        if let Some((got, want)) = self.width_fitted {
            reporter.say(&format!(
                "note: the measurement has {got} columns, the model {want}: fitted on the right"
            ));
        }
        if let Some(m) = metrics {
            summary += &format!(
                "\nPSNR {:.2} dB   SSIM {:.4}   SAM {:.2}°",
                m.psnr, m.ssim, m.sam_deg
            );
        }
        reporter.say(&summary);
        reporter.emit(&serde_json::to_value(report)?);
        Ok(())
    }
}
