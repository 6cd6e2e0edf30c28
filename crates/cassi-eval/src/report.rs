//! The study's files: `summary.json`, `outcomes.csv`, `parameters.csv` and
//! `report.md` (setup, conventions, tables, timings, machine), each written
//! atomically.

use std::fmt::Write;
use std::path::Path;

use crate::machine::Machine;
use crate::protocol::{SceneResult, Study};
use crate::records::{StudySetup, SummaryRecord, write_record};
use cassi_core::Parameter;

use crate::study_figures::Figure;
use crate::summary::Summary;
use crate::sweep_rows::Sweeps;
use crate::tables;

/// Where the scenes and mask came from, as the report should name them.
pub struct Setup<'a> {
    pub scenes: &'a str,
    pub mask: &'a str,
}

/// The study's files in `--out`, besides its folders (`scenes/`,
/// `figures/`, `sensitivity/`): what [`write_all`] writes.
pub const SUMMARY_FILE: &str = "summary.json";
pub const OUTCOMES_FILE: &str = "outcomes.csv";
pub const PARAMETERS_FILE: &str = "parameters.csv";
pub const REPORT_FILE: &str = "report.md";
pub const STUDY_FILES: [&str; 4] = [SUMMARY_FILE, OUTCOMES_FILE, PARAMETERS_FILE, REPORT_FILE];

/// Writes every study file into `out`.
pub fn write_all(
    out: &Path,
    setup: &Setup<'_>,
    study: &Study,
    results: &[SceneResult],
    summary: &Summary,
    sweeps: &Sweeps,
) -> anyhow::Result<()> {
    let machine = Machine::this();
    let record = SummaryRecord {
        study: study.clone(),
        setup: StudySetup {
            scenes: setup.scenes.to_string(),
            mask: setup.mask.to_string(),
        },
        machine: machine.clone(),
        summary: summary.clone(),
        sweeps: sweeps.clone(),
        metric_definitions: cassi_core::metrics::METRIC_DEFINITIONS.to_string(),
    };
    write_record(out.join(SUMMARY_FILE), &record)?;
    cassi_io::write_atomic(
        out.join(OUTCOMES_FILE),
        tables::outcomes_csv(results).as_bytes(),
    )?;
    cassi_io::write_atomic(
        out.join(PARAMETERS_FILE),
        tables::parameters_csv(results).as_bytes(),
    )?;
    let mut figures = crate::study_figures::write_summary_figures(
        out,
        results,
        summary,
        sweeps,
        study.preset.name(),
    )?;
    if let (Some(first), Some(method)) = (results.first(), study.methods.first())
        // written before, or earlier in the same output set
        && cassi_io::output_exists(out.join("figures/qualitative.png"))
    {
        figures.push(Figure {
            caption: format!(
                "{} ({}): pseudo-RGB of the truth and each scenario; below, per-pixel RMS error over bands on one shared colour scale",
                first.scene,
                method.name()
            ),
            path: "figures/qualitative.png".into(),
        });
        figures.push(Figure {
            caption: format!(
                "{} ({}): spectra at three pixels, truth vs scenarios",
                first.scene,
                method.name()
            ),
            path: "figures/spectra.png".into(),
        });
    }
    let md = markdown(setup, study, results, summary, sweeps, &figures, &machine);
    cassi_io::write_atomic(out.join(REPORT_FILE), md.as_bytes())?;
    Ok(())
}

/// The report as Markdown.
pub fn markdown(
    setup: &Setup<'_>,
    study: &Study,
    results: &[SceneResult],
    summary: &Summary,
    sweeps: &Sweeps,
    figures: &[Figure],
    machine: &Machine,
) -> String {
    let m = study.mismatch;
    let noise = match study.noise.photon_peak {
        Some(p) => format!(
            "Poisson shot noise at {p:.0} photo-electrons peak + Gaussian read noise σ = {} e⁻",
            study.noise.read_noise
        ),
        None => format!("Gaussian read noise σ = {}", study.noise.read_noise),
    };
    let methods: Vec<&str> = study.methods.iter().map(|m| m.name()).collect();
    let mut s = String::new();
    let _ = writeln!(s, "# CASSI self-calibration study\n");
    let _ = writeln!(s, "## Setup\n");
    let _ = writeln!(s, "- Scenes: {} ({} scenes)", setup.scenes, results.len());
    let _ = writeln!(s, "- Nominal mask: {}", setup.mask);
    let _ = writeln!(
        s,
        "- True mismatch: {} (nominal: {})",
        Parameter::format_all(&m),
        Parameter::format_all(&cassi_core::Mismatch::nominal(study.stride))
    );
    let _ = writeln!(
        s,
        "- Instrument dispersion model: `{}`{}",
        study.instrument.name(),
        if study.instrument.is_subpixel() {
            " (measurements simulated on a 2× finer grid and binned, so the oracle is no inverse crime)"
        } else {
            ""
        }
    );
    let _ = writeln!(s, "- Noise: {noise}; scene i uses noise seed i");
    let _ = writeln!(
        s,
        "- Calibration preset: `{}`, from the measurement and the nominal mask only",
        study.preset.name()
    );
    let _ = writeln!(s, "- Methods: {}", methods.join(", "));
    let _ = writeln!(
        s,
        "- Machine: {} ({} threads, {})\n",
        machine.cpu, machine.threads, machine.os
    );
    let _ = writeln!(s, "## Scenarios and conventions\n");
    let _ = writeln!(
        s,
        "- **I Ideal**: a perfectly aligned instrument, nominal model; reported noise-free and with the study's noise.\n\
         - **II Assumed**: the mismatched instrument's noisy measurement, reconstructed with the nominal model.\n\
         - **III Corrected**: the same measurement, reconstructed with the self-calibrated model.\n\
         - **IV Oracle**: the same measurement, reconstructed with the true model.\n\
         - Every scenario runs the same solver with the same settings; reconstructions are clipped to [0, 1] before scoring, nothing else.\n\
         - Coordinates: +dx moves the mask right (columns), +dy down (rows), θ rotates about the mask centre ((W−1)/2, (H−1)/2), +θ turns +col toward +row; band k lands a1·k·cos α columns right (and a1·k·sin α rows down).\n\
         - ρ = (III − II)/(IV − II) from mean PSNRs: the share of the mismatch loss that calibration recovers.\n"
    );
    if study
        .methods
        .iter()
        .any(|m| matches!(m, crate::method::StudyMethod::Learned(_)))
    {
        let _ = writeln!(
            s,
            "- Learned methods: MST-S/L are guided by the scenario's mask (nominal in I–II, moved to the calibrated pose in III, to the true pose in IV) with their trained step-2 dispersion (a1 and α are not inputs of the networks; the measurement is fitted to 310 columns); HDNet does not use the mask, so its II–IV coincide; PnP-HSICNN is a model-based solver and uses the whole model like the TV solvers.\n"
        );
    }
    let _ = writeln!(s, "## Results (means over scenes)\n");
    s += &tables::main_table(summary);
    let _ = writeln!(s);
    for method in &methods {
        let _ = writeln!(s, "### PSNR per scene, {method} (dB)\n");
        s += &tables::per_scene_table(results, method);
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Calibration: estimated vs true parameters\n");
    s += &tables::parameter_table(results, summary);
    if study.instrument == cassi_core::optics::DispersionModel::Rounded {
        let _ = writeln!(
            s,
            "\nWith the `rounded` model α is not identifiable (a sub-degree tilt rounds to no row offset) and a1 only to its rounding interval; α is left at 0 and its error is not meaningful."
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "## Calibration stages\n");
    s += &tables::stage_table(results);
    for (preset, points) in &sweeps.sensitivity {
        let _ = writeln!(
            s,
            "## Sensitivity to the mismatch size (`{preset}` preset)\n\nAll five parameters scaled together from the paper's (dx 1.5 px, dy 1.0 px, θ 0.3°, a1 − 2 = 0.04, α 0.5°); same scenes, noise and solver.\n"
        );
        s += &tables::sensitivity_table(points, preset);
        let _ = writeln!(s);
    }
    if let Some(rows) = &sweeps.ablation {
        let _ = writeln!(
            s,
            "## Ablation of the calibration pipeline\n\nThe same measurements reconstructed with the nominal model, with the parameters after each preset's search stages alone, after the whole preset, and with the true model.\n"
        );
        s += &tables::ablation_table(rows);
        let _ = writeln!(s);
    }
    if !figures.is_empty() {
        let _ = writeln!(s, "## Figures\n");
        for f in figures {
            let _ = writeln!(s, "![{}]({})\n\n*{}*\n", f.caption, f.path, f.caption);
        }
    }
    let _ = writeln!(
        s,
        "\nWhole study: {:.1} s for {} scenes (calibration and every reconstruction) on {} ({} threads).\n",
        summary.total_seconds,
        results.len(),
        machine.cpu,
        machine.threads
    );
    s += &tables::metric_footnote();
    s
}
