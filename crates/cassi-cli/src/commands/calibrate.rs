//! `cassi calibrate`: measurement + nominal mask → mismatch parameters.

use std::path::PathBuf;

use anyhow::Context;
use cassi_core::Parameter;
use cassi_core::calib::{
    A1_SHORT_TILT_DEG, BandEnd, Calibration, CalibrationProblem, Fit, Preset, SHARP_BLUR_PX,
    StageReport, calibrate,
};
use cassi_core::optics::{BandOffsets, BandSpread, DispersionModel, warp_mask};
use clap::Args;

use cassi_io::OutputSet;

use super::band_table::load_band_offsets;
use super::inputs::{MeasurementArgs, UncodedMask};
use crate::interrupt;
use crate::report::Reporter;
use crate::sidecar::recorded_band_spread;
use cassi_eval::records::sidecar_path;

#[derive(Args)]
pub struct CalibrateArgs {
    #[command(flatten)]
    pub input: MeasurementArgs,
    /// Search preset: `default` (ours: fast and precise) or `paper` (the
    /// paper's Algorithm 1: grids, then Adam through the unrolled proxy).
    #[arg(long, default_value = "default", value_parser = cassi_core::calib::PRESET_NAMES)]
    pub preset: String,
    /// Dispersion model of candidate instruments: `dispersed-mask` (the
    /// default preset's default, for real instruments: continuous a1 and α,
    /// the mask sampled once where each band lands, as a camera integrates
    /// it), `crisp-cells` (the same with each side of a pixel's mask edge
    /// blurred from where it lies: slower, and its error bars are not
    /// calibrated; see the README for when it helps), `subpixel` (the same dispersion with the mask interpolated
    /// twice; the paper preset's default) or `rounded` (whole-pixel band
    /// offsets, the reference code's model).
    #[arg(long)]
    pub model: Option<DispersionModel>,
    /// The dispersion's curvature the calibration holds, px per band²
    /// (band k lands a1·k + a2·k² along the dispersion): your prism's design
    /// value, if its dispersion is not linear in the band index. Not
    /// fitted. Default 0 (straight). Default preset only.
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub dispersion_a2: f64,
    /// Fit the dispersion's curvature a2 too, in the scene fit's fine pass
    /// (from `--dispersion-a2`, 0 by default), for a prism whose
    /// dispersion is not linear in the band index. a2's ± is the fine
    /// pass's own (README: Fitting the curvature). Default preset only.
    #[arg(long)]
    pub fit_curvature: bool,
    /// Leave out the blur pass, the default preset's last stage: σ as the
    /// scene fit leaves it. The pass refits σ alone on the crisp-cell model
    /// with GAP-TV's texture, the geometry held, on the middle quarter of
    /// the rows — σ nearer the truth on blurred instruments and above all
    /// on smooth scenes at a pose off the pixel grid, where the scene fit
    /// reads σ about 0.07 px low (README: the blur pass). Since stop 62 it
    /// starts from the texture fit's σ. About 0.35–0.6 s on a 256×256
    /// frame, 1–3 s on a 660×714 one. Default preset only.
    #[arg(long, conflicts_with = "blur_pass")]
    pub no_blur_pass: bool,
    /// The blur pass, on by default since stop 41 (kept so that scripts
    /// that asked for it still run; with `--preset paper` an error, as
    /// before).
    #[arg(long, hide = true)]
    pub blur_pass: bool,
    /// The rows the default preset's search stages (pose from several
    /// starts, dispersion hypotheses, their pose re-fits) run on: N middle
    /// rows of a taller frame (the most detailed N where those hold more
    /// than twice the middle's pixel-scale detail), or `all`. Default 256
    /// (a 660-row snapshot's search in a third of the time; the texture and
    /// scene fits always use every row).
    #[arg(long, value_name = "N|all", value_parser = search_rows)]
    pub search_rows: Option<SearchRows>,
    /// After the scene fit: profile its objective ±1.5 px along the dx–a1
    /// and dy–α ridges (band 0 or the last band moved, the other held),
    /// refit briefly from any second dip, and report the ends that score
    /// within 1 % of the answer — placements the data do not rule out,
    /// which the ± then reach. The answer is kept. About 30 % more time on
    /// a 256² frame, 48 s on a 660×714 one (Xeon VM; README: Ridge probes).
    /// Default preset, dispersed-mask model.
    #[arg(long)]
    pub ridge_probes: bool,
    /// Each band's position along the dispersion, held while the rest is
    /// fitted: a monochromator scan of your camera (px, one per band; .txt
    /// or .csv numbers, or a vector in .npy/.npz/.mat). The table's own
    /// line through band 0 is removed (dx and a1 fit it); what is left —
    /// the prism's departure from a1·k + a2·k² — is held in every
    /// candidate and written into the calibration, which `cassi
    /// reconstruct --calibration` then uses. Default preset only.
    #[arg(long, value_name = "FILE")]
    pub band_offsets: Option<PathBuf>,
    /// Variable name inside the --band-offsets file.
    #[arg(long, requires = "band_offsets")]
    pub band_offsets_var: Option<String>,
    /// Where each band's light lies along the dispersion in the fitted
    /// model: `uniform` (evenly over the band's width, a1 px: a spectrum
    /// constant within each band; the default with the default preset's
    /// dispersed-mask and crisp-cell models), `point` (at the band's
    /// position; the default with the paper preset and the rounded and
    /// subpixel models) or `linear` (a hat between its neighbours: a
    /// spectrum linear between band centres). A camera's light is
    /// continuous in wavelength, so each band's light spreads; σ is then
    /// the optics' blur alone. Written into the calibration, which `cassi
    /// reconstruct --calibration` then uses. Spread bands: default preset
    /// only.
    #[arg(long, value_name = "SPREAD", value_parser = str::parse::<BandSpread>)]
    pub band_spread: Option<BandSpread>,
    /// Output calibration JSON (for `cassi reconstruct --calibration`).
    #[arg(long, short)]
    pub output: PathBuf,
    /// Also write the calibrated (warped) mask here (.npy, .npz, .mat).
    #[arg(long)]
    pub write_mask: Option<PathBuf>,
}

/// The band spread to fit and where it came from: `--band-spread`, else
/// the spread the measurement's simulation sidecar records (the instrument
/// that made it, as its band count is taken from there) where the preset
/// can hold it, else the preset's default for `model`.
fn band_spread(
    args: &CalibrateArgs,
    preset: &Preset,
    model: DispersionModel,
) -> (BandSpread, String) {
    if let Some(spread) = args.band_spread {
        return (spread, "from --band-spread".into());
    }
    let measurement = &args.input.measurement;
    if let Some(spread) = recorded_band_spread(measurement)
        && preset.check_band_spread(spread).is_ok()
    {
        return (
            spread,
            format!(
                "as the simulation sidecar {} records (--band-spread to choose)",
                sidecar_path(measurement).display()
            ),
        );
    }
    let spread = preset.default_band_spread(model);
    let why = if spread.is_point() {
        "the default with this preset and model"
    } else {
        "the default: a camera's spectrum is continuous (--band-spread point for one position)"
    };
    (spread, why.into())
}

/// `--search-rows`: a count of middle rows, or every row.
#[derive(Debug, Clone, Copy)]
pub struct SearchRows(Option<usize>);

fn search_rows(s: &str) -> Result<SearchRows, String> {
    Preset::search_rows_from_str(s).map(SearchRows)
}

pub fn run(args: &CalibrateArgs, reporter: &Reporter) -> anyhow::Result<()> {
    // every file read and written, compared before any work
    check_output_json(&args.output)?;
    let mut set = OutputSet::new();
    args.input.declare_inputs(&mut set);
    if let Some(p) = &args.band_offsets {
        set.input("--band-offsets", p);
    }
    set.output("-o", &args.output);
    if let Some(p) = &args.write_mask {
        cassi_io::check_output_format(p)?;
        set.output("--write-mask", p);
    }
    let checked = set.check()?;
    let mut preset = Preset::by_name(&args.preset, args.input.stride)?
        .with_dispersion_a2(args.dispersion_a2)
        .context("--dispersion-a2")?;
    if args.no_blur_pass {
        preset = preset.without_blur_pass();
    }
    if args.blur_pass {
        preset = preset.with_blur_pass().context("--blur-pass")?;
    }
    if let Some(SearchRows(rows)) = args.search_rows {
        preset = preset.with_search_rows(rows).context("--search-rows")?;
    }
    if args.fit_curvature {
        preset = preset.with_fitted_curvature().context("--fit-curvature")?;
    }
    if args.ridge_probes {
        preset = preset.with_ridge_probes().context("--ridge-probes")?;
    }
    if args.band_offsets.is_some() {
        preset.check_band_offsets().context("--band-offsets")?;
    }
    let model = args.model.unwrap_or(preset.default_model());
    let (spread, spread_from) = band_spread(args, &preset, model);
    preset.check_band_spread(spread).context("--band-spread")?;
    let (measurement, mask, bands) = args.input.load(reporter, UncodedMask::Refuse)?;
    let offsets = args
        .band_offsets
        .as_deref()
        .map(|p| {
            load_band_offsets(
                p,
                args.band_offsets_var.as_deref(),
                bands,
                args.input.stride,
            )
        })
        .transpose()?;
    let mut problem =
        CalibrationProblem::nominal(&measurement, &mask, bands, args.input.stride, model)?;
    if let Some(o) = &offsets {
        problem = problem.with_band_offsets(o)?;
        reporter.say(&band_offsets_line(o));
    }
    if !spread.is_point() {
        problem = problem.with_band_spread(spread);
        reporter.say(&format!(
            "each band's light spread along the dispersion: {} over the bands' spacing (a1), \
             {spread_from}",
            spread.name()
        ));
    } else if args.band_spread.is_none() {
        reporter.say(&format!("each band's light at one position, {spread_from}"));
    }
    let mut on_stage = |s: &StageReport| {
        // between stages nothing is half-written: a signal ends the run here
        interrupt::stop_point();
        reporter.say(&stage_line(s));
        if let Some(other) = &s.passed_over {
            reporter.say(&format!(
                "  {:<20} {}  score {:.4e}  (passed over: scored higher)",
                "",
                Parameter::format_all(&other.parameters),
                other.score
            ));
        }
    };
    let cal = reporter.stage("calibrating", || {
        Ok(calibrate(&problem, &preset, &mut on_stage)?)
    })?;
    interrupt::check()?;
    let staging = checked.begin()?;
    cassi_eval::records::write_record(&args.output, &cal)?;
    if let Some(p) = &args.write_mask {
        cassi_io::save_frame(p, &warp_mask(&mask, &cal.parameters.pose()), "mask")?;
    }
    interrupt::check()?;
    staging.commit()?;
    reporter.say(&format!(
        "calibrated: {}\n{}\
         proxy residual {:.4e} (nominal model {:.4e}{}), {} evaluations, {:.1} s → {}",
        Parameter::format_all(&cal.parameters),
        uncertainty_lines(&cal) + &ridge_probe_hint(&cal),
        cal.score,
        cal.nominal_score,
        // the proxy reconstruction fits a sharp operator more easily, so
        // on real data a blurred model can score worse and still be right
        if cal.parameters.blur_sigma_px > 0.0 {
            "; not comparable: the calibrated model is blurred"
        } else {
            ""
        },
        cal.evaluations,
        cal.seconds,
        args.output.display()
    ));
    reporter.emit(&serde_json::to_value(&cal)?);
    Ok(())
}

/// What the calibration holds of a band table: its shape and the line the
/// fit carries instead.
fn band_offsets_line(o: &BandOffsets) -> String {
    let (k, worst) = o
        .as_slice()
        .iter()
        .enumerate()
        .fold((0, 0.0f64), |(bk, bv), (k, &v)| {
            if v.abs() > bv.abs() { (k, v) } else { (bk, bv) }
        });
    format!(
        "holding the band offsets: RMS {:.3} px off the table's line through band 0 (largest \
         {worst:+.3} px at band {k}); its slope {:.4} px per band is a1's to fit",
        o.rms(),
        o.table_line[1]
    )
}

/// A stage's line as it finishes: its name, answer, score, cost.
pub(crate) fn stage_line(s: &StageReport) -> String {
    format!(
        "  {:<20} {}  score {:.4e}  ({} evals, {:.2} s)",
        s.name,
        Parameter::format_all(&s.parameters),
        s.score,
        s.evaluations,
        s.seconds
    )
}

/// One line per estimated parameter with its standard error and, where
/// estimated, the half-width of its 95 % interval, then the pairs that
/// trade off.
fn uncertainty_lines(cal: &Calibration) -> String {
    estimate_lines(cal) + &wide_blur_note(cal) + &a1_tilt_note(cal)
}

/// Each estimate ± its standard error (and 95 % half-width), the σ to
/// reconstruct with where it differs, the trade-offs: what a single
/// calibration and a combination of several print alike.
pub(crate) fn estimate_lines(cal: &Calibration) -> String {
    let mut out = String::new();
    for line in Parameter::ALL
        .iter()
        .filter_map(|&p| cal.uncertainty_line(p))
    {
        out += &format!("  {line}\n");
    }
    out + &model_blur_line(cal) + &trade_off_lines(cal) + &ridge_probe_lines(cal)
}

/// The σ `cassi reconstruct --calibration` uses, where it is not the
/// reported one: the model's own fit (the blur pass's read on another
/// model), or the reported σ plus the on-grid margin.
pub(crate) fn model_blur_line(cal: &Calibration) -> String {
    let Some(sigma) = cal.model_blur_sigma_px else {
        return match cal.on_grid_margin_px {
            Some(margin) => format!(
                "  blur σ to reconstruct with: {:.3} px, the σ above + {margin:.3} px: on the \
                 pixel grid GAP-TV reconstructs better with more blur than the estimate (README: \
                 the on-grid margin)\n",
                cal.reconstruction_parameters().blur_sigma_px
            ),
            None => String::new(),
        };
    };
    // the two printed alike (the demo's 0.4753 and 0.4751) read as a contradiction
    let pass = if (sigma - cal.parameters.blur_sigma_px).abs() < 5e-4 {
        "the blur pass, read on another model, agrees to 0.001 px"
    } else {
        "the σ above is the blur pass's, read on another model: the instrument's"
    };
    // a combination of snapshots may hold both: the margin on top
    let margin = cal
        .on_grid_margin_px
        .map_or(String::new(), |m| format!(" + {m:.3} px on the pixel grid"));
    format!(
        "  blur σ to reconstruct with: {:.3} px, the {} model's own fit{margin} ({pass}; README: \
         the blur pass)\n",
        cal.reconstruction_parameters().blur_sigma_px,
        cal.model.name()
    )
}

/// A note when the fitted tilt is one at which the texture fit's a1
/// standard error ran short on the benchmark (see [`A1_SHORT_TILT_DEG`]);
/// the wide-blur note covers blurrier fits. The scene fit's a1 errors did
/// not grow with the tilt (tuning half: RMS 0.0070 at |α̂| ≥ 0.3° against
/// 0.0057 below), so it gets no note.
fn a1_tilt_note(cal: &Calibration) -> String {
    if cal.uncertainty_fit != Some(Fit::Texture) {
        return String::new();
    }
    let (alpha, blur) = (cal.parameters.alpha_deg, cal.parameters.blur_sigma_px);
    let (Some(_), Some(half_width)) = (
        cal.uncertainty.get(Parameter::A1),
        cal.interval_95.get(Parameter::A1),
    ) else {
        return String::new();
    };
    if alpha.abs() < A1_SHORT_TILT_DEG || blur.abs() > SHARP_BLUR_PX {
        return String::new();
    }
    format!(
        "  note: with the dispersion tilted (α {alpha:+.2}°), a1's ± ran short on the benchmark's \
         held-out instruments (within 1σ in about half of them); quote its 95 % interval, \
         ± {half_width:.4}, which held in all (README: error bars)\n"
    )
}

/// A note when the fitted blur is beyond the headline benchmark's range:
/// there the standard errors carry the floors measured on blurrier
/// instruments, which the calibration misplaced by up to a pixel or more.
fn wide_blur_note(cal: &Calibration) -> String {
    let blur = cal.parameters.blur_sigma_px;
    let (Some(_), Some(dx), Some(dx_95)) = (
        cal.uncertainty.get(Parameter::BlurSigmaPx),
        cal.uncertainty.get(Parameter::Dx),
        cal.interval_95.get(Parameter::Dx),
    ) else {
        return String::new();
    };
    if blur.abs() <= SHARP_BLUR_PX {
        return String::new();
    }
    format!(
        "  note: the fitted blur ({blur:.2} px) is beyond the benchmark's 0–{SHARP_BLUR_PX} px; on \
         simulated instruments this blurred the calibration reported offsets that were not \
         there, so the ± above carry the wider model-error floors measured there: ± {dx:.2} px \
         in dx, {dx_95:.2} px in its 95 % interval (README: wide blur)\n"
    )
}

/// One line per ridge probe that ended as an alternative, or one saying
/// none did (nothing when the probes did not run).
pub(crate) fn ridge_probe_lines(cal: &Calibration) -> String {
    let Some(report) = &cal.ridge_probes else {
        return String::new();
    };
    let alternatives: Vec<_> = report.alternatives().collect();
    if alternatives.is_empty() {
        let refits = match report.ends.len() {
            0 => "no dip within the margin".to_string(),
            n => format!(
                "{n} dip{} refitted, none ended elsewhere within the margin",
                if n == 1 { "" } else { "s" }
            ),
        };
        return format!(
            "  ridge probes, the objective profiled along dx–a1 and dy–α at either end band: \
             {refits}\n"
        );
    }
    let mut out = String::new();
    for e in alternatives {
        let band = match e.moved {
            BandEnd::First => "band 0",
            BandEnd::Last => "the last band",
        };
        out += &format!(
            "  alternative along {} ({band} {:+.2} px): {}  objective {:+.2} % of the answer's: \
             the data do not rule it out; the ± above reach it\n",
            e.ridge.label(),
            e.step_px,
            Parameter::format_all(&e.parameters),
            100.0 * e.relative_objective
        );
    }
    out
}

/// Where the scene fit's fine pass ended the calibration (its error bars'
/// fit says so) and the ridge probes did not run: one line pointing to
/// them. Why: on the five real snapshots every answer had neighbours along
/// the ridges that its ± did not reach, where the simulated benchmark had
/// none (README: "Ridge probes").
fn ridge_probe_hint(cal: &Calibration) -> String {
    let fine_pass = matches!(
        cal.uncertainty_fit,
        Some(Fit::SceneFinePass | Fit::ScenePoseAndSlopePass | Fit::SceneDetailPass)
    );
    if !fine_pass || cal.ridge_probes.is_some() {
        return String::new();
    }
    "  on a real camera the answer along dx–a1 and dy–α can be one of several placements a pixel \
     or so apart that the ± above do not reach: --ridge-probes looks for them (README: Ridge \
     probes)\n"
        .into()
}

/// One line per pair of parameters that trade off.
pub(crate) fn trade_off_lines(cal: &Calibration) -> String {
    let mut out = String::new();
    for t in &cal.trade_offs {
        out += &format!(
            "  {} and {} trade off (error correlation {:+.2}): the data pin their combination \
             better than either\n",
            t.a.name(),
            t.b.name(),
            t.correlation
        );
    }
    out
}

pub(crate) fn check_output_json(path: &std::path::Path) -> anyhow::Result<()> {
    if path.extension().and_then(|e| e.to_str()) != Some("json") {
        anyhow::bail!(
            "{}: the calibration is written as JSON; use a .json name",
            path.display()
        );
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use cassi_core::Mismatch;
    use cassi_core::calib::Uncertainty;

    /// A calibration at the nominal ψ but for α and σ, every standard error
    /// 0.01 and 95 % half-width 0.0606.
    pub(crate) fn calibration(alpha_deg: f64, blur_sigma_px: f64) -> Calibration {
        let stated = |v: f64| Uncertainty(Parameter::ALL.iter().map(|&p| (p, Some(v))).collect());
        Calibration {
            preset: "default".into(),
            model: DispersionModel::DispersedMask,
            parameters: Mismatch {
                alpha_deg,
                blur_sigma_px,
                ..Mismatch::nominal(2.0)
            },
            score: 0.0,
            nominal_score: 0.0,
            uncertainty: stated(0.01),
            interval_95: stated(0.0606),
            trade_offs: Vec::new(),
            uncertainty_fit: Some(Fit::Texture),
            ridge_probes: None,
            model_blur_sigma_px: None,
            on_grid_margin_px: None,
            snapshots: None,
            band_offsets: None,
            band_spread: BandSpread::Point,
            stages: Vec::new(),
            seconds: 0.0,
            evaluations: 0,
        }
    }

    /// The a1 note appears exactly for the texture fit's tilted fits within
    /// the benchmark's blur range, with a1's 95 % half-width.
    #[test]
    fn the_a1_note_names_tilted_fits_and_their_interval() {
        let note = uncertainty_lines(&calibration(-0.45, 0.5));
        assert!(
            note.contains("α -0.45°") && note.contains("± 0.0606"),
            "{note}"
        );
        for (alpha, blur) in [(0.1, 0.5), (-0.29, 0.0), (0.6, 1.3)] {
            let lines = uncertainty_lines(&calibration(alpha, blur));
            assert!(
                !lines.contains("a1's ± ran short"),
                "α {alpha} σ {blur}: {lines}"
            );
        }
        let mut none = calibration(0.6, 0.5);
        none.interval_95 = Uncertainty::default();
        assert!(!uncertainty_lines(&none).contains("ran short"));
        let mut scene = calibration(-0.45, 0.5);
        scene.uncertainty_fit = Some(Fit::Scene);
        assert!(!uncertainty_lines(&scene).contains("ran short"));
    }

    /// A σ whose 95 % interval reaches below 0 prints the range it leaves,
    /// bounded above only; one clear of 0, and every other parameter
    /// (signed offsets reach below 0 as they may), keep "± half-width".
    #[test]
    fn a_blur_interval_reaching_below_zero_is_printed_as_bounded_above() {
        let lines = uncertainty_lines(&calibration(0.0, 0.05));
        assert!(
            lines.contains("blur  0.050 ± 0.010 px   (95 %: 0.000 to 0.111, bounded above only)"),
            "{lines}"
        );
        assert!(
            lines.contains("α     +0.00 ± 0.01 °   (95 %: ± 0.06)"),
            "{lines}"
        );
        assert!(
            lines.contains("dx    +0.000 ± 0.010 px   (95 %: ± 0.061)"),
            "{lines}"
        );
        let clear = uncertainty_lines(&calibration(0.0, 0.5));
        assert!(
            clear.contains("blur  0.500 ± 0.010 px   (95 %: ± 0.061)"),
            "{clear}"
        );
        assert!(!clear.contains("bounded above only"), "{clear}");
        // the range the line prints, as the Python `ranges_95` returns it
        let near_zero = calibration(0.0, 0.05);
        let (low, high) = near_zero.range_95(Parameter::BlurSigmaPx).unwrap();
        assert!(low == 0.0 && (high - 0.1106).abs() < 1e-12, "{low} {high}");
        let (low, high) = near_zero.range_95(Parameter::Dx).unwrap();
        assert!((low + 0.0606).abs() < 1e-12 && (high - 0.0606).abs() < 1e-12);
        let (low, _) = calibration(0.0, 0.5)
            .range_95(Parameter::BlurSigmaPx)
            .unwrap();
        assert!((low - 0.4394).abs() < 1e-12, "{low}");
        let mut none = near_zero;
        none.interval_95 = Uncertainty::default();
        assert_eq!(none.range_95(Parameter::BlurSigmaPx), None);
    }

    /// The ridge probes' lines: nothing when they did not run, one line
    /// saying so when no dip came near, one per alternative naming its
    /// ridge, the band moved and where it ended.
    #[test]
    fn the_ridge_probe_lines_name_each_alternative() {
        use cassi_core::calib::{ProbeEnd, Ridge, RidgeProbeReport};
        let mut cal = calibration(0.0, 0.5);
        assert_eq!(ridge_probe_lines(&cal), "");
        // the texture fit's answer (the subpixel model): no fine pass to probe
        assert_eq!(ridge_probe_hint(&cal), "");
        cal.uncertainty_fit = Some(Fit::SceneDetailPass);
        assert!(ridge_probe_hint(&cal).contains("--ridge-probes"));
        cal.ridge_probes = Some(RidgeProbeReport {
            profiles: Vec::new(),
            ends: Vec::new(),
        });
        assert!(ridge_probe_lines(&cal).contains("no dip within the margin"));
        // the hint stands only where the probes could have run and did not
        assert_eq!(ridge_probe_hint(&cal), "");
        let end = |alternative: bool, dy: f64| ProbeEnd {
            ridge: Ridge::DyAlpha,
            moved: BandEnd::First,
            step_px: 1.0,
            dip_relative_objective: 0.01,
            parameters: Mismatch {
                dy,
                ..cal.parameters
            },
            distance_px: dy.abs(),
            relative_objective: if alternative { -0.0026 } else { 0.04 },
            alternative,
        };
        cal.ridge_probes = Some(RidgeProbeReport {
            profiles: Vec::new(),
            ends: vec![end(false, 0.9)],
        });
        let none = ridge_probe_lines(&cal);
        assert!(
            none.contains("1 dip refitted, none ended elsewhere"),
            "{none}"
        );
        cal.ridge_probes = Some(RidgeProbeReport {
            profiles: Vec::new(),
            ends: vec![end(true, 1.145), end(false, 0.9)],
        });
        let one = ridge_probe_lines(&cal);
        assert_eq!(one.lines().count(), 1, "{one}");
        assert!(
            one.contains("along dy–α (band 0 +1.00 px)")
                && one.contains("dy +1.145 px")
                && one.contains("-0.26 %")
                && one.contains("do not rule it out"),
            "{one}"
        );
    }

    /// The reconstruction-σ line: absent without a blur pass, naming the
    /// instrument's σ when the two differ, their agreement when they print
    /// alike, the margin where the answer is on the pixel grid.
    #[test]
    fn the_reconstruction_blur_line_says_whether_the_pass_moved_sigma() {
        let mut cal = calibration(0.0, 0.4753);
        assert_eq!(model_blur_line(&cal), "");
        cal.model_blur_sigma_px = Some(0.4751);
        let alike = model_blur_line(&cal);
        assert!(
            alike.contains("0.475 px") && alike.contains("agrees"),
            "{alike}"
        );
        cal.model_blur_sigma_px = Some(0.5);
        let apart = model_blur_line(&cal);
        assert!(
            apart.contains("0.500 px") && apart.contains("the instrument's"),
            "{apart}"
        );
        assert!(!apart.contains("agrees"), "{apart}");
        // the reported σ plus the on-grid margin
        cal.model_blur_sigma_px = None;
        cal.on_grid_margin_px = Some(0.03);
        let margin = model_blur_line(&cal);
        assert!(
            margin.contains("0.505 px") && margin.contains("+ 0.030 px"),
            "{margin}"
        );
        // both (a combination of snapshots): the σ reconstructed with, the margin named
        cal.model_blur_sigma_px = Some(0.5);
        let both = model_blur_line(&cal);
        assert!(
            both.contains("0.530 px") && both.contains("+ 0.030 px on the pixel grid"),
            "{both}"
        );
    }
}
