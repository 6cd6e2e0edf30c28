//! Where each band of a real snapshot lands: every TSA snapshot calibrated
//! by the default preset, then each band's shift along the dispersion
//! fitted from that answer (`cassi_core::calib::fit_band_shifts`, the fine
//! pass's objective) on the whole frame and on its top and bottom halves.
//!
//! Why: the real snapshots' objective is several times flatter along the
//! dx–a1 ridge than the simulator's, with neighbouring basins a pixel away,
//! and a fitted curvature moves the red end by only ≈ 0.2 px (stops 52–53).
//! The shifts measure the dispersion's shape band by band; a shape the
//! instrument has appears in both halves of one exposure (the same prism,
//! other scene content), one the fit makes of the scene does not.
//!
//! The control (`bench/band_shifts_control.sh`): the same on measurements
//! simulated from each snapshot's own reconstruction by the 4× oversampled
//! instrument with a straight prism (`--measurements DIR` reads their
//! `scene*.npy`): the shapes a straight dispersion leaves with this content.
//!
//! `--apply RECORD` (the test of a shared shape): instead of fitting, each
//! snapshot's fine-pass objective with its bands held at the mean whole-frame
//! shape of the *other* snapshots in RECORD (leave one out), at no shift, and
//! at that shape's opposite — a camera's shape lowers the objective of a
//! snapshot it was not measured on; on the control (a straight prism) it
//! should not. `--at RECORD` takes each snapshot's ψ from RECORD's
//! calibration instead of calibrating again.
//!
//! Run: `cargo run --release -p cassi-bench --bin band_shifts [-- --scene
//! NAME]… [--measurements DIR] [--at RECORD] [--apply RECORD] [--out PATH]` →
//! `bench/results/real/band_shifts/real.json` (or PATH, or $CASSI_BENCH_OUT).
//! Needs `../shared/data/real` (or $CASSI_SHARED_DATA) for the mask.

use anyhow::{Context, Result, anyhow, bail, ensure};
use cassi_bench::{TsaSnapshots, bench_out, scene_name, write_record};
use cassi_core::Mismatch;
use cassi_core::calib::{
    BandShiftFit, BandShifts, CalibrationProblem, Preset, StageReport, band_shift_scores,
    calibrate, fit_band_shifts,
};
use cassi_core::solvers::CglsParams;
use cassi_eval::machine::Machine;
use serde_json::json;

const BANDS: usize = 28;
/// CGLS iterations of `--apply`'s solves (no tolerance: all of them).
const SOLVE_TO_CONVERGENCE: usize = 600;
const STRIDE: f64 = 2.0;
const USAGE: &str =
    "band_shifts [--scene NAME]… [--measurements DIR] [--at RECORD] [--apply RECORD] [--out PATH]";

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

/// A band_shifts record read once: its path (for errors) and its cases.
struct Record {
    path: String,
    cases: Vec<serde_json::Value>,
}

impl Record {
    fn read(path: &str) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {path}"))?;
        let record: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{path}: not JSON"))?;
        match record["cases"].as_array() {
            Some(cases) => Ok(Self {
                path: path.to_string(),
                cases: cases.clone(),
            }),
            None => bail!("{path}: no `cases` (a band_shifts record has them)"),
        }
    }

    /// The case of `snapshot`.
    fn case(&self, snapshot: &str) -> Result<&serde_json::Value> {
        self.cases
            .iter()
            .find(|c| c["snapshot"] == snapshot)
            .ok_or_else(|| anyhow!("{}: no case for the snapshot {snapshot}", self.path))
    }

    /// The mean whole-frame shape of every snapshot but `snapshot` (refused
    /// with no other, or shapes of another band count).
    fn others_mean_shape(&self, snapshot: &str) -> Result<Vec<f64>> {
        let path = &self.path;
        let mut shapes = Vec::new();
        for case in self.cases.iter().filter(|c| c["snapshot"] != snapshot) {
            let whole = case["windows"]
                .as_array()
                .and_then(|w| w.iter().find(|w| w["window"] == "whole"))
                .ok_or_else(|| anyhow!("{path}: {} has no whole-frame fit", case["snapshot"]))?;
            let shape: Vec<f64> = serde_json::from_value(whole["shifts"]["shape"].clone())
                .with_context(|| format!("{path}: {}'s shape", case["snapshot"]))?;
            ensure!(
                shape.len() == BANDS,
                "{path}: {}'s shape has {} bands, expected {BANDS}",
                case["snapshot"],
                shape.len()
            );
            shapes.push(shape);
        }
        ensure!(
            !shapes.is_empty(),
            "{path}: no snapshot other than {snapshot}"
        );
        let n = shapes.len() as f64;
        Ok((0..BANDS)
            .map(|k| shapes.iter().map(|s| s[k]).sum::<f64>() / n)
            .collect())
    }
}

fn main() -> Result<()> {
    cassi_bench::exit_on_help(USAGE);
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let mut only: Vec<String> = Vec::new();
    let mut out: Option<String> = None;
    let mut measurements: Option<std::path::PathBuf> = None;
    let mut at: Option<String> = None;
    let mut apply: Option<String> = None;
    let mut it = argv.iter();
    while let Some(flag) = it.next() {
        let mut value = || {
            it.next()
                .cloned()
                .ok_or_else(|| anyhow!("{flag} needs a value"))
        };
        match flag.as_str() {
            "--scene" => only.push(value()?),
            "--out" => out = Some(value()?),
            "--measurements" => measurements = Some(value()?.into()),
            "--at" => at = Some(value()?),
            "--apply" => apply = Some(value()?),
            other => bail!("{other}: usage: {USAGE}"),
        }
    }
    let out = match out {
        Some(path) => {
            // the folder checked before the work starts
            let dir = std::path::Path::new(&path)
                .parent()
                .filter(|d| !d.as_os_str().is_empty());
            if let Some(dir) = dir {
                ensure!(dir.is_dir(), "--out {path}: no folder {}", dir.display());
            }
            path
        }
        None => bench_out("real/band_shifts/real.json")?,
    };
    // the records read once, before any work, and never written over
    for record in at.iter().chain(&apply) {
        let same = match (std::fs::canonicalize(record), std::fs::canonicalize(&out)) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        };
        ensure!(!same, "--out {out} is the record {record} this run reads");
    }
    let at = at.as_deref().map(Record::read).transpose()?;
    let apply = apply.as_deref().map(Record::read).transpose()?;
    let snapshots = TsaSnapshots::find(measurements.as_deref(), &only)?;
    let preset = Preset::by_name("default", STRIDE)?;
    let Preset::Default(default) = &preset else {
        bail!("the default preset is not the default's")
    };
    let settings = default
        .scene_fit
        .ok_or_else(|| anyhow!("the default preset has no scene fit"))?;
    let model = preset.default_model();
    // --apply's scores with each scene solved to convergence, so a change
    // is the shape's, not where a solve stopped (checked once: the pass's
    // own solve, which stops at a relative tolerance, gave the same changes
    // within 0.01 % of the objective — moving the bands either way lowering
    // it is the objective's, not the solver's)
    let mut converged = settings;
    if let Some(pass) = converged.fine_pass.as_mut() {
        pass.first_solve = CglsParams {
            iterations: SOLVE_TO_CONVERGENCE,
            tolerance: 0.0,
        };
    }
    let mut cases = Vec::new();
    for path in &snapshots.paths {
        let snapshot = scene_name(path);
        let meas = snapshots.load(path)?;
        let problem = CalibrationProblem::nominal(&meas, &snapshots.mask, BANDS, STRIDE, model)?;
        let cal = match &at {
            Some(record) => record.case(&snapshot)?["calibration"].clone(),
            None => {
                let mut quiet = |_: &StageReport| {};
                let cal = calibrate(&problem, &preset, &mut quiet)?;
                eprintln!("{snapshot}: calibrated in {:.1} s", cal.seconds);
                serde_json::to_value(&cal)?
            }
        };
        let psi: Mismatch = serde_json::from_value(cal["parameters"].clone())
            .with_context(|| format!("{snapshot}: the calibration's parameters"))?;
        eprintln!("{snapshot}: {psi:?}");
        if let Some(record) = &apply {
            let shape = record.others_mean_shape(&snapshot)?;
            let opposite: Vec<f64> = shape.iter().map(|v| -v).collect();
            let tables = [vec![0.0; BANDS], shape.clone(), opposite];
            let scores = band_shift_scores(&problem, &psi, &BandShiftFit::new(converged), &tables)?;
            let change = |i: usize| scores[i] / scores[0] - 1.0;
            eprintln!(
                "  objective {:.5}; with the others' shape {:+.2} %, its opposite {:+.2} %",
                scores[0],
                100.0 * change(1),
                100.0 * change(2)
            );
            cases.push(json!({
                "snapshot": snapshot,
                "calibration": cal,
                "others_mean_shape": shape,
                "score_unshifted": scores[0],
                "score_others_shape": scores[1],
                "score_opposite_shape": scores[2],
            }));
            continue;
        }
        let rows = meas.rows();
        let mut windows = Vec::new();
        let mut shapes: Vec<(String, BandShifts)> = Vec::new();
        for (window, range) in [
            ("whole", None),
            ("top", Some((0, rows / 2))),
            ("bottom", Some((rows / 2, rows))),
        ] {
            let started = std::time::Instant::now();
            let how = BandShiftFit {
                rows: range,
                ..BandShiftFit::new(settings)
            };
            let fitted = fit_band_shifts(&problem, &psi, &how)?;
            let seconds = started.elapsed().as_secs_f64();
            eprintln!(
                "  {window:<6} shape RMS {:.3} px, line {:+.3} {:+.4}/band, objective {:.5} -> {:.5} \
                 ({} evaluations, {seconds:.0} s)\n    shape {:+.2?}",
                fitted.shape_rms(),
                fitted.line[0],
                fitted.line[1],
                fitted.score_unshifted,
                fitted.score_shifted,
                fitted.evaluations,
                fitted.shape
            );
            windows.push(json!({
                "window": window,
                "rows": range.map(|(a, b)| vec![a, b]),
                "shifts": serde_json::to_value(&fitted)?,
                "shape_rms": fitted.shape_rms(),
                "seconds": seconds,
            }));
            shapes.push((window.to_string(), fitted));
        }
        // the halves' agreement: the shape's part they share and the part
        // one has alone
        let (top, bottom) = (&shapes[1].1.shape, &shapes[2].1.shape);
        let halves_difference_rms = rms(top.iter().zip(bottom).map(|(a, b)| a - b));
        let halves_mean_rms = rms(top.iter().zip(bottom).map(|(a, b)| (a + b) / 2.0));
        eprintln!(
            "  halves: mean shape RMS {halves_mean_rms:.3}, difference RMS {halves_difference_rms:.3}"
        );
        cases.push(json!({
            "snapshot": snapshot,
            "calibration": cal,
            "windows": windows,
            "halves_mean_shape_rms": halves_mean_rms,
            "halves_difference_rms": halves_difference_rms,
        }));
    }
    let record = json!({
        "bench": if apply.is_some() { "band_shifts --apply" } else { "band_shifts" },
        "preset": "default",
        "flags": argv,
        "measurements": snapshots.dir.display().to_string(),
        "machine": Machine::this(),
        "cases": cases,
    });
    write_record(&out, &record)?;
    eprintln!("wrote {out}");
    Ok(())
}
