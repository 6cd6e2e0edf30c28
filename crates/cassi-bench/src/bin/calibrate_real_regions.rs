//! How well one real snapshot agrees with itself: each of the five TSA
//! snapshots calibrated by the default preset on bands of its rows (the
//! top and bottom halves, or thirds), each band with the mask's same rows.
//!
//! Why: the five snapshots' a1 spread (issue 14's target 0.005) needs a
//! measured reference. Two regions of one exposure share the camera, the
//! exposure and the mask seating, so their disagreement is what the
//! calibration's answer varies by with the scene content alone — and a
//! difference of one sign on all five snapshots is a property of the camera
//! (a dispersion or pose that varies down the field), which one global ψ
//! cannot hold.
//!
//! Cropping rows is nearly exact for this model: the dispersion runs along
//! the columns, so a detector row sees only its own mask row, up to dy, θ,
//! α and the blur, which move light across a band's edge by about 2 px at
//! most on these snapshots (legoman: dy 1.3 px, α −0.9° over 54 px). Each
//! band's pose is about its own centre: one rotation θ about the frame's
//! centre gives a band whose centre lies `h` rows below it the shift
//! dx − θ·h (θ in radians; 0.03 px for θ 0.01° and 165 rows), so the
//! record keeps each band's `centre_offset_rows` and the table compares
//! dx + θ·h, the frame-centred shift.
//!
//! The control (`bench/real_regions_control.sh`): the same regions of
//! measurements simulated from each snapshot's own reconstruction at its
//! own calibrated ψ (the 4× oversampled instrument: crisp mask cells, blur,
//! shot and read noise), where the truth is one ψ for every region —
//! `--measurements DIR` reads their `scene*.npy` instead, and each region's
//! record carries the simulation sidecar's truth.
//!
//! Run: `cargo run --release -p cassi-bench --bin calibrate_real_regions
//! [-- --regions whole|halves|thirds] [--scene NAME]… [--measurements DIR
//! [--label LABEL]]` → `bench/results/real/regions/<real|control|LABEL>_
//! <regions>[_<NAME>…].json` (or $CASSI_BENCH_OUT).
//! Needs `../shared/data/real` (or $CASSI_SHARED_DATA) for the mask.

use anyhow::{Context, Result, anyhow, bail, ensure};
use cassi_bench::{TsaSnapshots, bench_out, scene_name};
use cassi_core::calib::{CalibrationProblem, Preset, StageReport, calibrate};
use serde_json::json;

const BANDS: usize = 28;
const STRIDE: f64 = 2.0;

/// How the rows are split.
#[derive(Clone, Copy)]
enum Regions {
    Whole,
    Halves,
    Thirds,
}

impl Regions {
    fn parse(v: &str) -> Result<Self> {
        match v {
            "whole" => Ok(Self::Whole),
            "halves" => Ok(Self::Halves),
            "thirds" => Ok(Self::Thirds),
            other => bail!("--regions {other}: expected whole, halves or thirds"),
        }
    }

    fn key(self) -> &'static str {
        match self {
            Self::Whole => "whole",
            Self::Halves => "halves",
            Self::Thirds => "thirds",
        }
    }

    /// (name, first row, end row) of each band of `rows` rows, top first.
    fn bands(self, rows: usize) -> Vec<(&'static str, usize, usize)> {
        match self {
            Self::Whole => vec![("whole", 0, rows)],
            Self::Halves => vec![("top", 0, rows / 2), ("bottom", rows / 2, rows)],
            Self::Thirds => vec![
                ("top", 0, rows / 3),
                ("middle", rows / 3, 2 * rows / 3),
                ("bottom", 2 * rows / 3, rows),
            ],
        }
    }
}

/// A simulated measurement's true ψ, from its sidecar (`x.json` beside
/// `x.npy`); null for a real snapshot.
fn truth_of(path: &std::path::Path) -> Result<serde_json::Value> {
    let sidecar = path.with_extension("json");
    if !sidecar.exists() {
        return Ok(serde_json::Value::Null);
    }
    let text = std::fs::read_to_string(&sidecar)
        .with_context(|| format!("reading {}", sidecar.display()))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", sidecar.display()))?;
    let truth = value["simulation"]["mismatch"].clone();
    ensure!(
        truth.is_object(),
        "{}: no simulation.mismatch (a `cassi simulate` sidecar has one)",
        sidecar.display()
    );
    Ok(truth)
}

fn main() -> Result<()> {
    cassi_bench::exit_on_help(
        "calibrate_real_regions [--regions whole|halves|thirds] [--scene NAME]… [--measurements DIR \
         [--label NAME]]",
    );
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let mut regions = Regions::Halves;
    let mut only: Vec<String> = Vec::new();
    let mut measurements: Option<std::path::PathBuf> = None;
    let mut label: Option<String> = None;
    let mut it = argv.iter();
    while let Some(flag) = it.next() {
        let mut value = || {
            it.next()
                .cloned()
                .ok_or_else(|| anyhow!("{flag} needs a value"))
        };
        match flag.as_str() {
            "--regions" => regions = Regions::parse(&value()?)?,
            "--scene" => only.push(value()?),
            "--measurements" => measurements = Some(value()?.into()),
            "--label" => label = Some(value()?),
            other => bail!(
                "{other}: usage: calibrate_real_regions [--regions whole|halves|thirds] \
                 [--scene NAME]… [--measurements DIR [--label NAME]]"
            ),
        }
    }
    ensure!(
        label.is_none() || measurements.is_some(),
        "--label names a control's record: it needs --measurements DIR"
    );
    let source = match (&measurements, &label) {
        (None, _) => "real".to_string(),
        (Some(_), None) => "control".to_string(),
        (Some(_), Some(l)) => l.clone(),
    };
    let suffix: String = only.iter().map(|o| format!("_{o}")).collect();
    let out = bench_out(&format!(
        "real/regions/{source}_{}{suffix}.json",
        regions.key()
    ))?;
    let snapshots = TsaSnapshots::find(measurements.as_deref(), &only)?;
    let mask = &snapshots.mask;
    let preset = Preset::by_name("default", STRIDE)?;
    let model = preset.default_model();
    let mut cases = Vec::new();
    for path in &snapshots.paths {
        let snapshot = scene_name(path);
        let meas = snapshots.load(path)?;
        let truth = truth_of(path)?;
        for (region, first, end) in regions.bands(meas.rows()) {
            let m = meas.rows_range(first, end)?;
            let k = mask.rows_range(first, end)?;
            let problem = CalibrationProblem::nominal(&m, &k, BANDS, STRIDE, model)?;
            let mut quiet = |_: &StageReport| {};
            let cal = calibrate(&problem, &preset, &mut quiet)?;
            let p = &cal.parameters;
            eprintln!(
                "{snapshot} {region:<6} rows {first}..{end}: dx {:+.3} dy {:+.3} θ {:+.4}° a1 {:.4} \
                 α {:+.3}° σ {:.3}  ({:.1} s)",
                p.dx, p.dy, p.theta_deg, p.a1, p.alpha_deg, p.blur_sigma_px, cal.seconds
            );
            cases.push(json!({
                "snapshot": snapshot,
                "region": region,
                "first_row": first,
                "end_row": end,
                // rows the region's centre lies below the frame's centre
                "centre_offset_rows": (first + end) as f64 / 2.0 - meas.rows() as f64 / 2.0,
                "truth": truth,
                "calibration": serde_json::to_value(&cal)?,
            }));
        }
    }
    let record = json!({
        "regions": regions.key(),
        "preset": "default",
        "measurements": snapshots.dir.display().to_string(),
        "frame_rows": mask.rows(),
        "threads": rayon::current_num_threads(),
        "cases": cases,
    });
    cassi_io::write_atomic(&out, serde_json::to_string_pretty(&record)?.as_bytes())?;
    eprintln!("wrote {out}");
    Ok(())
}
