//! The flags of `cassi reconstruct` and what they name: the inputs, the
//! assumed instrument's parameters (a calibration or sidecar file) and the
//! files the command writes.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use cassi_core::calib::Calibration;
use cassi_core::optics::{BandOffsets, BandSpread, DispersionModel, validate_mismatch_for_mask};
use cassi_core::recon::MethodId;
use cassi_core::recon::registry::all_names;
use cassi_core::{Mismatch, Parameter};
use cassi_eval::records::{JsonFile, Record, SimulationRecord, json_kind};
use cassi_io::{CheckedSet, OutputSet};
use clap::Args;
use clap::builder::TypedValueParser;

use crate::commands::inputs::{LayoutArg, MeasurementArgs, parse_iterations, parse_weight};

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
    pub method: MethodId,
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

/// Every registry name, for `--method` (listed in `--help` whether or not
/// the networks are built in).
fn method_names() -> impl TypedValueParser<Value = MethodId> {
    clap::builder::PossibleValuesParser::new(all_names())
        .map(|name| MethodId::parse(&name).expect("clap passes only registry names"))
}

/// What `--calibration` names: the parameters, the dispersion model where
/// the file has one, the band offsets where a calibration held them.
pub struct ModelFile {
    pub parameters: Mismatch,
    pub model: Option<DispersionModel>,
    pub band_offsets: Option<BandOffsets>,
    /// Where each band's light lies along the dispersion (a calibration's;
    /// a point otherwise).
    pub band_spread: BandSpread,
}

/// The model parameters and dispersion model `--calibration` names. Three
/// shapes are accepted:
/// - a calibration record (`cassi calibrate`'s output): its "parameters",
///   "model" and "band_offsets" (where it held them);
/// - a simulation sidecar: its "simulation" → "mismatch" and "model" (the
///   true instrument: the oracle model);
/// - a parameter file written by hand: the parameters' object itself
///   (`{dx, dy, theta_deg, a1, alpha_deg[, blur_sigma_px]}`), or wrapped as
///   `{"parameters": {…}[, "model": …]}`, without the rest of a calibration.
///
/// The two records are read through [`cassi_eval::records`] (a newer
/// version, or another kind of record, is refused naming the file). In every
/// shape the parameters are an object with exactly the named fields (never
/// read by position), every value a number in range.
pub fn read_model_file(path: &Path) -> anyhow::Result<ModelFile> {
    let file = JsonFile::read(path)?;
    let v = file.value();
    let named_at = |params: &serde_json::Value, field: &str| {
        named_mismatch(params).with_context(|| format!("{}: {field}", path.display()))
    };
    let mut band_spread = BandSpread::Point;
    let (m, model, field, band_offsets) = match file.format()? {
        Some(Calibration::FORMAT) => {
            let field = "\"parameters\"";
            let m = named_at(&v["parameters"], field)?;
            let cal = file.parse::<Calibration>()?.record;
            // σ the model's own fit where the calibration kept one
            let m = Mismatch {
                blur_sigma_px: cal.reconstruction_parameters().blur_sigma_px,
                ..m
            };
            band_spread = cal.band_spread;
            (m, Some(cal.model), field, cal.band_offsets)
        }
        Some(SimulationRecord::FORMAT) => {
            let field = "\"simulation\".\"mismatch\"";
            let m = named_at(&v["simulation"]["mismatch"], field)?;
            let sidecar = file.parse::<SimulationRecord>()?.record;
            (m, Some(sidecar.simulation.model), field, None)
        }
        Some(other) => bail!(
            "{} is a {other} record, not a calibration, a simulation sidecar or a parameter file",
            path.display()
        ),
        None => match v.get("parameters") {
            Some(params) => {
                let field = "\"parameters\"";
                let model = v
                    .get("model")
                    .map(|m| serde_json::from_value(m.clone()))
                    .transpose()
                    .with_context(|| format!("{}: \"model\"", path.display()))?;
                (named_at(params, field)?, model, field, None)
            }
            None => {
                let m = named_mismatch(v).with_context(|| {
                    format!(
                        "{}: not a calibration or a simulation sidecar, and as a parameter object",
                        path.display()
                    )
                })?;
                (m, None, "the parameters", None)
            }
        },
    };
    m.validate()
        .with_context(|| format!("{}: {field}", path.display()))?;
    Ok(ModelFile {
        parameters: m,
        model,
        band_offsets,
        band_spread,
    })
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

impl ReconstructArgs {
    /// Checks every output (the cube, its .png and .json) against every
    /// input before any work; see [`cassi_io::OutputSet`].
    pub(crate) fn check_files(&self) -> anyhow::Result<CheckedSet> {
        cassi_io::check_output_format(&self.output)?;
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
    pub(crate) fn model_parameters(&self, mask: &cassi_core::Mask) -> anyhow::Result<ModelFile> {
        match &self.calibration {
            Some(path) => {
                let file = read_model_file(path)?;
                validate_mismatch_for_mask(&file.parameters, mask.rows(), mask.cols())
                    .with_context(|| format!("{}", path.display()))?;
                Ok(file)
            }
            None => Ok(ModelFile {
                parameters: Mismatch::nominal(self.input.stride),
                model: None,
                band_offsets: None,
                band_spread: BandSpread::Point,
            }),
        }
    }

    /// The instrument a solver assumes: `file`'s parameters, `model`, and
    /// its band offsets where the calibration held them (checked against
    /// the cube's bands, naming the file).
    pub(crate) fn assumed<'m>(
        &self,
        mask: &'m cassi_core::Mask,
        bands: usize,
        file: &'m ModelFile,
        model: DispersionModel,
    ) -> anyhow::Result<cassi_core::recon::Model<'m>> {
        let assumed =
            cassi_core::recon::Model::new(mask, bands, self.input.stride, file.parameters, model)?;
        let named = || match &self.calibration {
            Some(path) => format!("{}: \"band_offsets\"", path.display()),
            None => "the band offsets".into(),
        };
        assumed
            .holding(file.band_offsets.as_ref(), file.band_spread)
            .with_context(named)
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
