//! `cassi combine`: several snapshots' calibrations of one instrument →
//! one calibration, with whether the snapshots agree.

use std::path::PathBuf;

use cassi_core::Parameter;
use cassi_core::calib::{
    Calibration, CalibrationProblem, CombineParams, Preset, combine_snapshots, refit_jointly,
};
use cassi_eval::records::read_record;
use clap::Args;

use cassi_io::OutputSet;

use super::calibrate::{check_output_json, estimate_lines, stage_line};
use super::inputs::{MeasurementArgs, UncodedMask};
use crate::report::Reporter;

#[derive(Args)]
pub struct CombineArgs {
    /// Two or more calibration files (`cassi calibrate -o`), each of one
    /// snapshot of the same instrument — the same mask file, stride, model
    /// and preset; the scenes should differ: a scene's bias is what combining
    /// averages.
    #[arg(required = true, num_args = 2..)]
    pub calibrations: Vec<PathBuf>,
    /// Output calibration JSON (for `cassi reconstruct --calibration`): the
    /// combined answer, the snapshots' answers and their agreement.
    #[arg(long, short)]
    pub output: PathBuf,
    /// The snapshots' measurements (.mat, .npy, .npz), one per calibration
    /// and in their order: the combination is then refitted on them as one
    /// fit (one ψ, each snapshot its own scene, the scene fit's detail and
    /// fine passes) from the combination's answer — the geometry the joint
    /// fit's, σ and every error bar the combination's. Default preset's
    /// calibrations; needs --mask.
    #[arg(long, num_args = 2.., value_name = "MEASUREMENT", requires = "mask")]
    pub joint: Vec<PathBuf>,
    /// The nominal coded aperture the snapshots were calibrated with (with
    /// --joint).
    #[arg(long, requires = "joint")]
    pub mask: Option<PathBuf>,
    /// Variable name inside the measurement files (with --joint).
    #[arg(long, requires = "joint")]
    pub meas_var: Option<String>,
    /// Variable name inside the mask file (with --joint).
    #[arg(long, requires = "joint")]
    pub mask_var: Option<String>,
    /// Number of bands (with --joint; default as for `cassi calibrate`).
    #[arg(long, requires = "joint")]
    pub bands: Option<usize>,
    /// Nominal dispersion stride, px per band (with --joint; the one the
    /// snapshots were calibrated with).
    #[arg(
        long,
        default_value_t = 2.0,
        allow_hyphen_values = true,
        requires = "joint"
    )]
    pub stride: f64,
}

impl CombineArgs {
    /// Each --joint measurement with the mask and its options, as
    /// `cassi calibrate` reads them.
    fn joint_inputs(&self) -> Vec<MeasurementArgs> {
        let Some(mask) = &self.mask else {
            return Vec::new();
        };
        self.joint
            .iter()
            .map(|m| MeasurementArgs {
                measurement: m.clone(),
                meas_var: self.meas_var.clone(),
                mask: mask.clone(),
                mask_var: self.mask_var.clone(),
                bands: self.bands,
                stride: self.stride,
            })
            .collect()
    }
}

pub fn run(args: &CombineArgs, reporter: &Reporter) -> anyhow::Result<()> {
    check_output_json(&args.output)?;
    let mut set = OutputSet::new();
    for p in &args.calibrations {
        set.input("calibration", p);
    }
    let joint = args.joint_inputs();
    if !joint.is_empty() && joint.len() != args.calibrations.len() {
        anyhow::bail!(
            "--joint: {} measurements for {} calibrations; give one per calibration, in the same order",
            joint.len(),
            args.calibrations.len()
        );
    }
    for m in &joint {
        m.declare_inputs(&mut set);
    }
    set.output("-o", &args.output);
    let checked = set.check()?;
    let snapshots = args
        .calibrations
        .iter()
        .map(|p| Ok(read_record::<Calibration>(p)?))
        .collect::<anyhow::Result<Vec<_>>>()?;
    for (p, c) in args.calibrations.iter().zip(&snapshots) {
        if c.snapshots.is_some() {
            anyhow::bail!(
                "{} is itself a combination; combine the snapshots' own calibrations",
                p.display()
            );
        }
    }
    let refs: Vec<&Calibration> = snapshots.iter().collect();
    let combined = combine_snapshots(&refs, &CombineParams::default()).map_err(|e| {
        anyhow::anyhow!(
            "{e} (snapshot i is the i-th file: {})",
            args.calibrations
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    })?;
    let combination = combined.parameters;
    let combined = match joint.is_empty() {
        true => combined,
        false => refit(&combined, &joint, reporter)?,
    };
    let staging = checked.begin()?;
    cassi_eval::records::write_record(&args.output, &combined)?;
    staging.commit()?;
    let mut text = String::new();
    for (p, c) in args.calibrations.iter().zip(&snapshots) {
        text += &format!(
            "  {}  {}\n",
            Parameter::format_all(&c.parameters),
            p.display()
        );
    }
    if combined
        .snapshots
        .as_ref()
        .is_some_and(|s| s.joint_fit_from.is_some())
    {
        text += &format!(
            "combination ({} snapshots): {}\njoint fit (one ψ, each snapshot its own scene; σ and \
             the error bars the combination's): {}\n",
            snapshots.len(),
            Parameter::format_all(&combination),
            Parameter::format_all(&combined.parameters)
        );
    } else {
        text += &format!(
            "combined ({} snapshots): {}\n",
            snapshots.len(),
            Parameter::format_all(&combined.parameters)
        );
    }
    text += &combined_lines(&combined, &args.calibrations, &snapshots);
    text += &format!("→ {}", args.output.display());
    reporter.say(&text);
    reporter.emit(&serde_json::to_value(&combined)?);
    Ok(())
}

/// `combined` refitted jointly on the `joint` measurements (in the
/// snapshots' order), with the preset and model its snapshots were
/// calibrated with.
fn refit(
    combined: &Calibration,
    joint: &[MeasurementArgs],
    reporter: &Reporter,
) -> anyhow::Result<Calibration> {
    let first = &joint[0];
    let preset = Preset::by_name(&combined.preset, first.stride)?
        .with_dispersion_a2(combined.parameters.a2)?;
    let Preset::Default(preset) = preset else {
        anyhow::bail!(
            "--joint: the snapshots were calibrated with the {} preset; the joint fit is the default \
             preset's scene fit",
            combined.preset
        );
    };
    let loaded = joint
        .iter()
        .map(|m| m.load(reporter, UncodedMask::Refuse))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let bands = loaded[0].2;
    for (m, (_, _, b)) in joint.iter().zip(&loaded) {
        if *b != bands {
            anyhow::bail!(
                "--joint: {} holds {b} bands, {} holds {bands}: one instrument, one band count",
                m.measurement.display(),
                first.measurement.display()
            );
        }
    }
    let problems = loaded
        .iter()
        .map(|(y, mask, _)| {
            CalibrationProblem::nominal(y, mask, bands, first.stride, combined.model)?
                .holding(combined.band_offsets.as_ref(), combined.band_spread)
        })
        .collect::<cassi_core::Result<Vec<_>>>()?;
    let refit = reporter.stage("refitting the snapshots jointly", || {
        Ok(refit_jointly(combined, &problems, &preset)?)
    })?;
    for stage in &refit.stages[combined.stages.len()..] {
        reporter.say(&stage_line(stage));
    }
    Ok(refit)
}

/// The combined errors, then where the snapshots disagree beyond their
/// own error bars (the combined ± is then their scatter's), naming the
/// file farthest out (`files` and `snapshots`: the snapshots' calibration
/// files and calibrations, in order).
fn combined_lines(cal: &Calibration, files: &[PathBuf], snapshots: &[Calibration]) -> String {
    let mut out = estimate_lines(cal);
    let Some(spread) = &cal.snapshots else {
        return out;
    };
    let disagree: Vec<_> = spread.consistency.iter().filter(|c| c.disagree).collect();
    if disagree.is_empty() {
        out += "  the snapshots agree within their error bars on every parameter\n";
    }
    for c in disagree {
        let p = c.parameter;
        let prec = p.decimals();
        // the snapshot farthest out, by file, with its own answer and error
        let at = c.farthest.and_then(|i| files.get(i).zip(snapshots.get(i)));
        let farthest = match at {
            Some((f, s)) => format!(
                ", most of all {} ({} ± {:.prec$} {})",
                f.display(),
                p.format(p.get(&s.parameters)),
                s.uncertainty.get(p).unwrap_or(f64::NAN),
                p.unit()
            ),
            None => String::new(),
        };
        out += &format!(
            "  {}: the snapshots disagree beyond their error bars (spread {:.prec$} {}, χ² {:.1} on \
             {} dof, p {:.1e}){farthest}: a scene's bias, or an error bar too small; the combined \
             ± is their scatter's\n",
            p.name(),
            c.spread,
            p.unit(),
            c.chi_squared,
            c.dof,
            c.p_value,
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snapshot(dx: f64) -> Calibration {
        let mut c = super::super::calibrate::tests::calibration(0.0, 0.0);
        c.parameters.dx = dx;
        c
    }

    /// Disagreeing snapshots are named per parameter; agreeing ones say so.
    #[test]
    fn the_lines_name_the_parameters_the_snapshots_disagree_on() {
        let apart = [snapshot(0.0), snapshot(0.1), snapshot(1.0)];
        let refs: Vec<&Calibration> = apart.iter().collect();
        let c = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        let files: Vec<PathBuf> = ["a.json", "b.json", "c.json"].map(PathBuf::from).into();
        let text = combined_lines(&c, &files, &apart);
        assert!(text.contains("dx: the snapshots disagree"), "{text}");
        // without c the others agree best
        assert!(
            text.contains("most of all c.json (+1.000 ± 0.010 px)"),
            "{text}"
        );
        assert!(!text.contains("dy: the snapshots disagree"), "{text}");
        let alike = [snapshot(0.0), snapshot(0.001)];
        let refs: Vec<&Calibration> = alike.iter().collect();
        let c = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        assert!(
            combined_lines(&c, &[], &[])
                .contains("agree within their error bars on every parameter")
        );
    }
}
