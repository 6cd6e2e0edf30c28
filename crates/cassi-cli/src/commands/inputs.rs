//! Argument groups shared by subcommands: where the scene and the mask come
//! from, the mismatch, the noise.

use std::path::PathBuf;

use anyhow::{Context, bail};
use cassi_core::limits::check_elements;
use cassi_core::optics::{DispersionModel, MaskCode, NoiseModel, mask_code, validate_measurement};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Cube, Instrument, Mask, Mismatch, Parameter};
use cassi_eval::records::Source;
use cassi_io::{CubeLayout, OutputSet};
use clap::{Args, ValueEnum};

use crate::report::Reporter;
use crate::sidecar::{existing_sidecar, recorded_bands};
use cassi_eval::records::sidecar_path;

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
    /// Curvature of the true dispersion, px per band² (band k lands at
    /// a1·k + a2·k²; default 0, a straight dispersion).
    #[arg(long, allow_hyphen_values = true)]
    pub a2: Option<f64>,
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
        let m = self.over(base);
        m.validate().context("mismatch parameters")?;
        Ok(m)
    }

    /// The value a flag gives parameter `p`, if it was given.
    fn flag(&self, p: Parameter) -> Option<f64> {
        match p {
            Parameter::Dx => self.dx,
            Parameter::Dy => self.dy,
            Parameter::ThetaDeg => self.theta,
            Parameter::A1 => self.a1,
            Parameter::AlphaDeg => self.alpha,
            Parameter::A2 => self.a2,
            // the blur is set by `simulate --blur` (with the physical simulator's other settings)
            Parameter::BlurSigmaPx => None,
        }
    }

    /// `base` with every parameter given by a flag replaced.
    pub fn over(&self, mut base: Mismatch) -> Mismatch {
        for p in Parameter::ALL {
            if let Some(v) = self.flag(p) {
                p.set(&mut base, v);
            }
        }
        base
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
    check_elements(
        "the synthetic scene",
        &[args.bands, args.size, args.size],
        &format!(
            "--bands {} × --size {} × {}",
            args.bands, args.size, args.size
        ),
    )?;
    let spec = SceneSpec {
        rows: args.size,
        cols: args.size,
        wavelengths_nm: Instrument::with_bands(args.bands, 2.0)?.wavelengths_nm,
        seed: args.scene_seed,
    };
    let cube = synthetic_scene(&spec).with_context(|| {
        format!(
            "synthetic scene (--size {}, --bands {})",
            args.size, args.bands
        )
    })?;
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
    /// Number of bands (default: the simulation sidecar's, else 28 when the
    /// measurement's width fits 28 bands; anything else is an error asking
    /// for --bands).
    #[arg(long)]
    pub bands: Option<usize>,
    /// Nominal dispersion stride, px per band.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub stride: f64,
}

/// What a command does with a mask that codes nothing (all open, or one
/// gray level): reconstruction can still run, calibration cannot.
#[derive(Clone, Copy)]
pub enum UncodedMask {
    Warn,
    Refuse,
}

/// The band count a measurement is assumed to hold when nothing says
/// otherwise: the benchmark instruments' 28.
pub const DEFAULT_BANDS: usize = 28;

impl MeasurementArgs {
    /// Loads and checks both files (a measurement with light in it, a mask
    /// that lets light through, rows that agree, a width that fits the band
    /// count, a problem within the element budget); returns them with the
    /// band count, and says on the terminal where the count came from when
    /// it was not given.
    pub fn load(
        &self,
        reporter: &Reporter,
        uncoded: UncodedMask,
    ) -> anyhow::Result<(cassi_core::Measurement, Mask, usize)> {
        Instrument::with_bands(1, self.stride).context("--stride")?;
        let measurement = cassi_io::load_frame(&self.measurement, self.meas_var.as_deref())?;
        let mask = cassi_io::load_frame(&self.mask, self.mask_var.as_deref())?;
        let mask_what = format!("mask {}", self.mask.display());
        cassi_core::optics::validate_mask(&mask, &mask_what)?;
        if let MaskCode::Uniform(v) = mask_code(&mask, &mask_what)? {
            match uncoded {
                UncodedMask::Warn => reporter.warn(&format!(
                    "{mask_what}: every pixel transmits {v}: nothing is coded, so the bands \
                     overlap uncoded on the detector"
                )),
                UncodedMask::Refuse => bail!(
                    "{mask_what}: every pixel transmits {v}: an uncoded aperture leaves no \
                     pattern to calibrate against"
                ),
            }
        }
        validate_measurement(&measurement, &self.measurement.display().to_string())?;
        if measurement.rows() != mask.rows() {
            bail!(
                "{}: the measurement has {} rows but the mask {} has {}; the detector has the \
                 mask's rows",
                self.measurement.display(),
                measurement.rows(),
                self.mask.display(),
                mask.rows()
            );
        }
        let (bands, origin) = self.band_count(measurement.cols(), mask.cols())?;
        check_elements(
            "the reconstructed cube",
            &[bands, mask.rows(), mask.cols()],
            &format!("{bands} bands {origin}"),
        )?;
        if self.bands.is_none() {
            reporter.say(&format!("bands: {bands} ({origin})"));
        }
        Ok((measurement, mask, bands))
    }

    /// Declares the files this reads — the measurement, the mask and the
    /// measurement's simulation sidecar (which describes it: never an
    /// output) — as inputs of `set`.
    pub fn declare_inputs(&self, set: &mut OutputSet) {
        set.input("the measurement", &self.measurement)
            .input("--mask", &self.mask);
        if let Some(sidecar) = existing_sidecar(&self.measurement) {
            set.input("the measurement's simulation sidecar", sidecar);
        }
    }

    /// The band count and where it came from: --bands, the measurement's
    /// simulation sidecar, or the default 28 when the width fits it. Never a
    /// guess: a width that fits none of these is an error that shows the
    /// arithmetic.
    fn band_count(&self, det_cols: usize, mask_cols: usize) -> anyhow::Result<(usize, String)> {
        let meas = self.measurement.display();
        let s = self.stride;
        if det_cols < mask_cols {
            bail!(
                "{meas}: the measurement ({det_cols} columns) is narrower than the mask \
                 {} ({mask_cols} columns); the detector is the mask's width plus the dispersion",
                self.mask.display()
            );
        }
        let extra = det_cols - mask_cols;
        if let Some(bands) = self.bands {
            if bands == 0 {
                bail!("--bands must be at least 1");
            }
            if !width_fits(bands, s, extra) {
                bail!(
                    "{meas}: {det_cols} columns do not fit --bands {bands}: a {mask_cols}-column \
                     mask with {bands} bands at stride {s} needs {mask_cols} + ({bands} − 1)·{s} \
                     = {} columns (± {} for a drifted prism)",
                    mask_cols as f64 + (bands - 1) as f64 * s,
                    width_slack(bands, s)
                );
            }
            return Ok((bands, "from --bands".into()));
        }
        if let Some(bands) = recorded_bands(&self.measurement)
            && width_fits(bands, s, extra)
        {
            return Ok((
                bands,
                format!(
                    "from the simulation sidecar {}",
                    sidecar_path(&self.measurement).display()
                ),
            ));
        }
        if width_fits(DEFAULT_BANDS, s, extra) {
            return Ok((
                DEFAULT_BANDS,
                format!(
                    "the default: {det_cols} columns fit a {mask_cols}-column mask with \
                     {DEFAULT_BANDS} bands at stride {s}"
                ),
            ));
        }
        let implied = extra as f64 / s + 1.0;
        bail!(
            "{meas}: cannot tell the band count: {det_cols} columns with a {mask_cols}-column \
             mask leave {extra} extra columns; {DEFAULT_BANDS} bands at stride {s} would need \
             {mask_cols} + {}·{s} = {} (± {}), and (L − 1)·{s} = {extra} means L = {implied:.2}. \
             Pass --bands (and --stride) to say what the instrument is",
            DEFAULT_BANDS - 1,
            mask_cols as f64 + (DEFAULT_BANDS - 1) as f64 * s,
            width_slack(DEFAULT_BANDS, s)
        )
    }
}

/// How far a measurement's width may stray from the nominal
/// mask + (L − 1)·stride: a drifted prism (a1 ≠ stride, rounding, the
/// subpixel model's ceil) widens or narrows it by up to ~10 % of the spread.
fn width_slack(bands: usize, stride: f64) -> usize {
    ((0.1 * (bands - 1) as f64 * stride).ceil() as usize).max(2)
}

/// Whether `extra` detector columns beyond the mask fit `bands` at `stride`.
fn width_fits(bands: usize, stride: f64, extra: usize) -> bool {
    let nominal = (bands - 1) as f64 * stride;
    (extra as f64 - nominal).abs() <= width_slack(bands, stride) as f64
}

/// The most iterations a solver flag accepts: far beyond any useful run
/// (the defaults are 100–124), short of a run that would never end.
pub const MAX_ITERATIONS: usize = 100_000;

/// `--iterations`: 1 … [`MAX_ITERATIONS`].
pub fn parse_iterations(text: &str) -> Result<usize, String> {
    let n: usize = text
        .parse()
        .map_err(|_| format!("'{text}' is not a whole number of iterations"))?;
    if !(1..=MAX_ITERATIONS).contains(&n) {
        return Err(format!("must be between 1 and {MAX_ITERATIONS}"));
    }
    Ok(n)
}

/// `--weight`: a denoiser strength, finite and ≥ 0.
pub fn parse_weight(text: &str) -> Result<f32, String> {
    let w: f32 = text
        .parse()
        .map_err(|_| format!("'{text}' is not a number"))?;
    if !(w.is_finite() && w >= 0.0) {
        return Err("must be a finite number ≥ 0 (the TV weight)".into());
    }
    Ok(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_fit_their_band_count_within_a_drift() {
        // 256-column mask, 28 bands at stride 2: 310 nominal; a1 2.04 rounded
        // gives 311, subpixel 312.
        for extra in [54, 55, 56, 52, 60] {
            assert!(width_fits(28, 2.0, extra), "{extra}");
        }
        assert!(!width_fits(28, 2.0, 61));
        assert!(!width_fits(28, 2.0, 11));
        // the 256×300 mask with a 311-column measurement: 11 extra
        // columns fit neither 28 bands nor a whole band count at stride 2
        assert!(!width_fits(DEFAULT_BANDS, 2.0, 11));
    }
}
