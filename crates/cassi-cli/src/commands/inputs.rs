//! Argument groups shared by subcommands: where the scene and the mask come
//! from, the mismatch, the noise.

use std::path::PathBuf;

use anyhow::{Context, bail};
use cassi_core::optics::{DispersionModel, NoiseModel};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Cube, Instrument, Mask, Mismatch};
use cassi_io::CubeLayout;
use clap::{Args, ValueEnum};

use crate::sidecar::Source;

#[derive(Clone, Copy, ValueEnum)]
pub enum LayoutArg {
    /// Guess from the file type and the axis sizes.
    Auto,
    /// (bands, rows, cols): the .npy convention.
    Brc,
    /// (rows, cols, bands): the .mat benchmark convention.
    Rcb,
}

impl From<LayoutArg> for CubeLayout {
    fn from(l: LayoutArg) -> Self {
        match l {
            LayoutArg::Auto => CubeLayout::Auto,
            LayoutArg::Brc => CubeLayout::BandsRowsCols,
            LayoutArg::Rcb => CubeLayout::RowsColsBands,
        }
    }
}

#[derive(Args)]
pub struct SceneArgs {
    /// Scene cube file (.mat, .npy, .npz), values in [0, 1].
    #[arg(
        long,
        conflicts_with = "synthetic",
        required_unless_present = "synthetic"
    )]
    pub scene: Option<PathBuf>,
    /// Variable (array) name inside the scene file.
    #[arg(long)]
    pub scene_var: Option<String>,
    /// Axis order of the scene array.
    #[arg(long, value_enum, default_value = "auto")]
    pub layout: LayoutArg,
    /// Use the embedded procedural scene instead of a file.
    #[arg(long)]
    pub synthetic: bool,
    /// Synthetic scene: rows and cols.
    #[arg(long, default_value_t = 256)]
    pub size: usize,
    /// Synthetic scene: number of bands.
    #[arg(long, default_value_t = 28)]
    pub bands: usize,
    /// Synthetic scene: seed.
    #[arg(long, default_value_t = 0)]
    pub scene_seed: u64,
}

#[derive(Args)]
pub struct MaskArgs {
    /// Coded-aperture file (.mat, .npy, .npz), values in [0, 1].
    #[arg(
        long,
        conflicts_with = "random_mask",
        required_unless_present = "random_mask"
    )]
    pub mask: Option<PathBuf>,
    /// Variable name inside the mask file.
    #[arg(long)]
    pub mask_var: Option<String>,
    /// Use an i.i.d. random binary mask of the scene's size.
    #[arg(long)]
    pub random_mask: bool,
    /// Random mask: seed.
    #[arg(long, default_value_t = 1)]
    pub mask_seed: u64,
    /// Random mask: fraction of open pixels.
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    pub open_fraction: f64,
}

#[derive(Args)]
pub struct InstrumentArgs {
    /// Nominal dispersion stride, detector pixels per band.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub stride: f64,
}

#[derive(Args)]
pub struct MismatchArgs {
    /// Start from the paper's mismatch (dx 1.5, dy 1.0, θ 0.3°, a1 2.04, α 0.5°)
    /// instead of none; the flags below override single values.
    #[arg(long)]
    pub paper_mismatch: bool,
    /// Mask shift along columns, px (+ = right).
    #[arg(long, allow_hyphen_values = true)]
    pub dx: Option<f64>,
    /// Mask shift along rows, px (+ = down).
    #[arg(long, allow_hyphen_values = true)]
    pub dy: Option<f64>,
    /// Mask rotation, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub theta: Option<f64>,
    /// True dispersion slope, px per band (default: the nominal stride).
    #[arg(long, allow_hyphen_values = true)]
    pub a1: Option<f64>,
    /// Dispersion axis angle, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub alpha: Option<f64>,
    /// Model of the true instrument's dispersion.
    #[arg(long, default_value = "rounded")]
    pub model: DispersionModel,
}

#[derive(Args)]
pub struct NoiseArgs {
    /// Photo-electrons at the measurement's maximum (Poisson shot noise).
    #[arg(long, default_value_t = 1e5, allow_hyphen_values = true)]
    pub photon_peak: f64,
    /// Gaussian read-noise σ in electrons (at the --photon-peak scale).
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true)]
    pub read_noise: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 0)]
    pub noise_seed: u64,
    /// Make a noise-free measurement.
    #[arg(long)]
    pub no_noise: bool,
}

impl MismatchArgs {
    pub fn mismatch(&self, stride: f64) -> anyhow::Result<Mismatch> {
        let base = if self.paper_mismatch {
            Mismatch::paper()
        } else {
            Mismatch::nominal(stride)
        };
        let m = Mismatch {
            dx: self.dx.unwrap_or(base.dx),
            dy: self.dy.unwrap_or(base.dy),
            theta_deg: self.theta.unwrap_or(base.theta_deg),
            a1: self.a1.unwrap_or(base.a1),
            alpha_deg: self.alpha.unwrap_or(base.alpha_deg),
        };
        m.validate().context("mismatch parameters")?;
        Ok(m)
    }
}

impl NoiseArgs {
    pub fn noise(&self) -> anyhow::Result<Option<NoiseModel>> {
        if self.no_noise {
            return Ok(None);
        }
        let n = NoiseModel {
            photon_peak: Some(self.photon_peak),
            read_noise: self.read_noise,
            seed: self.noise_seed,
        };
        n.validate().context("noise parameters")?;
        Ok(Some(n))
    }
}

/// The scene cube and where it came from.
pub fn load_scene(args: &SceneArgs) -> anyhow::Result<(Cube, Source)> {
    if let Some(path) = &args.scene {
        let cube = cassi_io::load_cube(path, args.scene_var.as_deref(), args.layout.into())?;
        let (l, h, w) = cube.shape();
        let source = Source::File {
            path: path.clone(),
            variable: args.scene_var.clone(),
            shape: vec![l, h, w],
        };
        return Ok((cube, source));
    }
    if args.bands == 0 {
        bail!("--bands must be at least 1");
    }
    let spec = SceneSpec {
        rows: args.size,
        cols: args.size,
        wavelengths_nm: Instrument::with_bands(args.bands, 2.0)?.wavelengths_nm,
        seed: args.scene_seed,
    };
    let cube = synthetic_scene(&spec).context("synthetic scene")?;
    let source = Source::Synthetic {
        seed: args.scene_seed,
        rows: args.size,
        cols: args.size,
        bands: args.bands,
    };
    Ok((cube, source))
}

/// The nominal mask (of the scene's size when random) and where it came from.
pub fn load_mask(args: &MaskArgs, rows: usize, cols: usize) -> anyhow::Result<(Mask, Source)> {
    if let Some(path) = &args.mask {
        let mask = cassi_io::load_frame(path, args.mask_var.as_deref())?;
        cassi_core::optics::validate_mask(&mask, &format!("mask {}", path.display()))?;
        let source = Source::File {
            path: path.clone(),
            variable: args.mask_var.clone(),
            shape: vec![mask.rows(), mask.cols()],
        };
        return Ok((mask, source));
    }
    let mask = random_binary_mask(rows, cols, args.open_fraction, args.mask_seed)
        .context("random mask")?;
    let source = Source::Random {
        seed: args.mask_seed,
        open_fraction: args.open_fraction,
        rows,
        cols,
    };
    Ok((mask, source))
}

/// A measurement and the nominal mask it was taken with (calibrate, reconstruct).
#[derive(Args)]
pub struct MeasurementArgs {
    /// The measurement (.mat, .npy, .npz): (rows, detector cols).
    pub measurement: PathBuf,
    /// Variable name inside the measurement file.
    #[arg(long)]
    pub meas_var: Option<String>,
    /// The nominal coded aperture.
    #[arg(long)]
    pub mask: PathBuf,
    /// Variable name inside the mask file.
    #[arg(long)]
    pub mask_var: Option<String>,
    /// Number of bands (default: from the measurement width and the stride).
    #[arg(long)]
    pub bands: Option<usize>,
    /// Nominal dispersion stride, px per band.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub stride: f64,
}

impl MeasurementArgs {
    /// Loads and checks both files; returns them with the band count.
    pub fn load(&self) -> anyhow::Result<(cassi_core::Measurement, Mask, usize)> {
        let measurement = cassi_io::load_frame(&self.measurement, self.meas_var.as_deref())?;
        let mask = cassi_io::load_frame(&self.mask, self.mask_var.as_deref())?;
        cassi_core::optics::validate_mask(&mask, &format!("mask {}", self.mask.display()))?;
        let bands = match self.bands {
            Some(b) => b,
            None => {
                infer_bands(measurement.cols(), mask.cols(), self.stride).with_context(|| {
                    format!(
                        "{}: cannot infer the band count; pass --bands",
                        self.measurement.display()
                    )
                })?
            }
        };
        Ok((measurement, mask, bands))
    }
}

/// L such that (L − 1)·stride best explains the extra detector columns.
fn infer_bands(det_cols: usize, mask_cols: usize, stride: f64) -> anyhow::Result<usize> {
    if det_cols < mask_cols {
        bail!(
            "the measurement ({det_cols} columns) is narrower than the mask ({mask_cols} columns)"
        );
    }
    if !(stride.is_finite() && stride > 0.0) {
        bail!("--stride must be positive");
    }
    Ok(((det_cols - mask_cols) as f64 / stride).floor() as usize + 1)
}
