//! `cassi simulate`: scene + mask + mismatch + noise → measurement + sidecar.

use std::path::PathBuf;

use anyhow::{Context, bail};
use cassi_core::Instrument;
use cassi_core::limits::check_elements;
use cassi_core::optics::{
    BandSpread, DispersionModel, DispersionStep, Halo, MaskCode, PhysicalSpec, SimulationSpec,
    mask_code, physical_detector_shape, validate_mismatch_for_mask,
};
use cassi_eval::jobs::simulation::{SimulationInputs, declare_outputs, simulate_and_record};
use cassi_eval::records::sidecar_path;
use cassi_io::OutputSet;
use clap::Args;

use super::inputs::{
    InstrumentArgs, MaskArgs, MismatchArgs, NoiseArgs, SceneArgs, load_mask, load_scene,
};
use crate::interrupt;
use crate::observer::CliObserver;
use crate::report::Reporter;

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
    #[command(flatten)]
    pub physical: PhysicalArgs,
    /// Output measurement (.npy, .npz or .mat); a JSON sidecar goes beside it.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Also write a 16-bit PNG preview of the measurement beside it.
    #[arg(long)]
    pub preview: bool,
}

/// The physical instrument (`--oversample` and what needs it).
#[derive(Args)]
pub struct PhysicalArgs {
    /// Simulate the physical instrument on an N× finer grid (crisp mask
    /// squares, the scene interpolated, continuous dispersion, blur, binning
    /// to detector pixels) instead of a discrete --model (not with --model).
    #[arg(long, value_name = "N", value_parser = parse_oversample, conflicts_with = "model",
          allow_hyphen_values = true)]
    pub oversample: Option<usize>,
    /// Optical blur: Gaussian σ in detector pixels (at the middle wavelength
    /// when --blur-slope is given).
    #[arg(long, value_name = "SIGMA", requires = "oversample", value_parser = parse_blur,
          allow_hyphen_values = true)]
    pub blur: Option<f64>,
    /// Wavelength-dependent blur: σ(λ) = SIGMA + S·(λ − λ_c), px per nm, λ_c
    /// the middle of the band wavelengths' range.
    #[arg(long, value_name = "S", requires = "oversample", allow_hyphen_values = true,
          value_parser = parse_blur_slope)]
    pub blur_slope: Option<f64>,
    /// A fixed detector size (the real data's convention: the sensor crop is
    /// fixed by the design, its origin at detector pixel (0, 0), and light
    /// beyond it is lost). ROWS must be the mask's rows. Default: the mask's
    /// rows × (W + ⌈max_k d_k⌉).
    #[arg(long, value_name = "ROWSxCOLS", requires = "oversample", value_parser = parse_detector)]
    pub detector: Option<(usize, usize)>,
    /// Quantise the electron counts to 2^B levels of the full well (= the
    /// photon peak, at the clean measurement's maximum): 1 … 24 bits.
    #[arg(long, value_name = "B", requires = "oversample", value_parser = parse_adc_bits,
          allow_hyphen_values = true)]
    pub adc_bits: Option<u32>,
    /// A wide skirt under the blur: SHARE of every point's light spread by a
    /// Gaussian of SIGMA detector pixels, the rest by --blur (a lens's
    /// scatter; no calibration model has one).
    #[arg(long, value_name = "SHARE,SIGMA", requires = "oversample", value_parser = parse_halo)]
    pub halo: Option<Halo>,
    /// A prism whose dispersion is not linear in the band index: band k
    /// lands a1·k + A2·k² px along the dispersion (no calibration model has
    /// this term).
    #[arg(long, value_name = "A2", requires = "oversample", allow_hyphen_values = true,
          value_parser = parse_dispersion_a2)]
    pub dispersion_a2: Option<f64>,
    /// A step in the dispersion: band K and every later band land PX px
    /// further along it (no calibration model has this; a study of what
    /// the band-shift fit can see).
    #[arg(long, value_name = "K:PX", requires = "oversample", allow_hyphen_values = true,
          value_parser = str::parse::<DispersionStep>)]
    pub dispersion_step: Option<DispersionStep>,
    /// Where each band's light lies along the dispersion: `point` (at the
    /// band's position, the default and every calibration model's
    /// assumption), `uniform` (evenly between the midpoints to its
    /// neighbours: a spectrum constant within each band) or `linear` (a hat
    /// between the neighbours' positions: a spectrum linear between band
    /// centres) — a real camera's light is continuous in wavelength.
    #[arg(long, value_name = "SPREAD", requires = "oversample",
          value_parser = str::parse::<BandSpread>)]
    pub band_spread: Option<BandSpread>,
}

impl PhysicalArgs {
    /// The physical spec, or `None` without `--oversample`.
    pub fn spec(&self) -> anyhow::Result<Option<PhysicalSpec>> {
        let Some(oversample) = self.oversample else {
            return Ok(None);
        };
        let spec = PhysicalSpec {
            oversample,
            blur_sigma_px: self.blur.unwrap_or(0.0),
            blur_slope_px_per_nm: self.blur_slope.unwrap_or(0.0),
            detector: self.detector,
            adc_bits: self.adc_bits,
            halo: self.halo,
            dispersion_a2: self.dispersion_a2.unwrap_or(0.0),
            dispersion_step: self.dispersion_step,
            band_spread: self.band_spread.unwrap_or_default(),
        };
        spec.validate().context("physical instrument")?;
        Ok(Some(spec))
    }
}

/// `--oversample`: a whole number ≥ 1.
fn parse_oversample(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "'{text}': expected a whole number ≥ 1 of fine grid points per detector pixel \
             (benchmarks use 4)"
        )),
    }
}

/// `--blur`: σ in detector pixels, finite, 0 … 100.
fn parse_blur(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v)
            if v.is_finite()
                && (0.0..=cassi_core::optics::physical::MAX_BLUR_SIGMA_PX).contains(&v) =>
        {
            Ok(v)
        }
        _ => Err(format!(
            "'{text}': expected a blur σ in detector pixels, 0 … {}",
            cassi_core::optics::physical::MAX_BLUR_SIGMA_PX
        )),
    }
}

/// `--blur-slope`: a finite number of px per nm.
fn parse_blur_slope(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("'{text}': expected a finite slope in px per nm")),
    }
}

/// `--detector ROWSxCOLS`, both ≥ 1.
pub fn parse_detector(text: &str) -> Result<(usize, usize), String> {
    let parsed = text.split_once(['x', 'X', '×']).and_then(|(r, c)| {
        Some((
            r.trim().parse::<usize>().ok()?,
            c.trim().parse::<usize>().ok()?,
        ))
    });
    match parsed {
        Some((r, c)) if r >= 1 && c >= 1 => Ok((r, c)),
        _ => Err(format!(
            "--detector: expected ROWSxCOLS (two whole numbers ≥ 1, e.g. 256x310), got '{text}'"
        )),
    }
}

/// `--halo SHARE,SIGMA`: a share in [0, 1) and a σ in (0, 100] px.
fn parse_halo(text: &str) -> Result<Halo, String> {
    let bad = || {
        format!(
            "'{text}': expected SHARE,SIGMA — the halo's share of the light, 0 … <1, and its σ in \
             detector pixels, >0 … {} (e.g. 0.3,2)",
            cassi_core::optics::physical::MAX_BLUR_SIGMA_PX
        )
    };
    let (a, b) = text.split_once(',').ok_or_else(bad)?;
    let halo = Halo {
        share: a.trim().parse().map_err(|_| bad())?,
        sigma_px: b.trim().parse().map_err(|_| bad())?,
    };
    let spec = PhysicalSpec {
        halo: Some(halo),
        ..PhysicalSpec::default()
    };
    spec.validate().map_err(|_| bad())?;
    Ok(halo)
}

/// `--dispersion-a2`: px per band², within ± the simulator's limit.
fn parse_dispersion_a2(text: &str) -> Result<f64, String> {
    let max = cassi_core::optics::physical::MAX_DISPERSION_A2;
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= max => Ok(v),
        _ => Err(format!(
            "'{text}': expected the dispersion's curvature in px per band², −{max} … {max}"
        )),
    }
}

/// `--adc-bits`: 1 … 24.
fn parse_adc_bits(text: &str) -> Result<u32, String> {
    let max = cassi_core::optics::physical::MAX_ADC_BITS;
    match text.parse::<u32>() {
        Ok(b) if (1..=max).contains(&b) => Ok(b),
        _ => Err(format!(
            "'{text}': expected a whole number of bits, 1 … {max}"
        )),
    }
}

pub fn run(args: &SimulateArgs, reporter: &Reporter) -> anyhow::Result<()> {
    cassi_io::check_output_format(&args.output)?;
    // every file read and written, compared before any work
    let mut set = OutputSet::new();
    if let Some(p) = &args.scene.scene {
        set.input("--scene", p);
    }
    if let Some(p) = &args.mask.mask {
        set.input("--mask", p);
    }
    declare_outputs(&mut set, "-o", &args.output, args.preview);
    let checked = set.check()?;
    // Parameters first: a typo should not cost a scene load.
    Instrument::with_bands(1, args.instrument.stride).context("--stride")?;
    let physical = args.physical.spec()?;
    let mut mismatch = args.mismatch.mismatch(args.instrument.stride)?;
    // the sidecar's true parameters carry the blur, so `--calibration` with
    // it gives the oracle (blurred) model
    mismatch.blur_sigma_px = physical.map_or(0.0, |p| p.blur_sigma_px);
    let spec = SimulationSpec {
        mismatch,
        // the physical instrument's S = 1 limit is the subpixel model
        model: if physical.is_some() {
            DispersionModel::Subpixel
        } else {
            args.mismatch.model
        },
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
    if let Some(physical) = &physical {
        physical
            .blur_sigmas(&instrument.wavelengths_nm)
            .context("--blur/--blur-slope")?;
        if let Some((rows, cols)) = physical.detector {
            if rows != mask.rows() {
                bail!(
                    "--detector {rows}x{cols}: the detector has the mask's {} rows (calibrate and \
                     reconstruct read measurements with the mask's rows); only its width may \
                     differ from the default",
                    mask.rows()
                );
            }
            check_elements("the measurement", &[rows, cols], "from --detector")?;
        }
        let (rows, cols) = physical_detector_shape(
            mask.rows(),
            mask.cols(),
            scene.bands(),
            &spec.mismatch,
            physical,
        )?;
        if cols < mask.cols() {
            reporter.warn(&format!(
                "--detector {rows}x{cols} is narrower than the mask ({} columns): the light of \
                 the mask's right-hand columns is lost even in band 0",
                mask.cols()
            ));
        }
    }
    let inputs = SimulationInputs {
        scene,
        scene_source,
        mask,
        mask_source,
        instrument,
        spec,
        physical,
    };
    let staging = checked.begin()?;
    let (measurement, record) = simulate_and_record(
        &inputs,
        &args.output,
        args.preview,
        &mut CliObserver::new(reporter),
    )?;
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
