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
//! Run: `cargo run --release -p cassi-bench --bin band_shifts [-- --scene
//! NAME]… [--measurements DIR] [--out PATH]` →
//! `bench/results/real/band_shifts.json` (or PATH, or $CASSI_BENCH_OUT).
//! Needs `../shared/data/real` (or $CASSI_SHARED_DATA) for the mask.

use anyhow::{Result, anyhow, bail, ensure};
use cassi_bench::{TsaSnapshots, bench_out, scene_name, write_record};
use cassi_core::calib::{
    BandShiftFit, BandShifts, CalibrationProblem, Preset, StageReport, calibrate, fit_band_shifts,
};
use cassi_eval::machine::Machine;
use serde_json::json;

const BANDS: usize = 28;
const STRIDE: f64 = 2.0;
const USAGE: &str = "band_shifts [--scene NAME]… [--measurements DIR] [--out PATH]";

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

fn main() -> Result<()> {
    cassi_bench::exit_on_help(USAGE);
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let mut only: Vec<String> = Vec::new();
    let mut out: Option<String> = None;
    let mut measurements: Option<std::path::PathBuf> = None;
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
        None => bench_out("real/band_shifts.json")?,
    };
    let snapshots = TsaSnapshots::find(measurements.as_deref(), &only)?;
    let preset = Preset::by_name("default", STRIDE)?;
    let Preset::Default(default) = &preset else {
        bail!("the default preset is not the default's")
    };
    let settings = default
        .scene_fit
        .ok_or_else(|| anyhow!("the default preset has no scene fit"))?;
    let model = preset.default_model();
    let mut cases = Vec::new();
    for path in &snapshots.paths {
        let snapshot = scene_name(path);
        let meas = snapshots.load(path)?;
        let problem = CalibrationProblem::nominal(&meas, &snapshots.mask, BANDS, STRIDE, model)?;
        let mut quiet = |_: &StageReport| {};
        let cal = calibrate(&problem, &preset, &mut quiet)?;
        let psi = cal.parameters;
        eprintln!("{snapshot}: {psi:?} ({:.1} s)", cal.seconds);
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
            "calibration": serde_json::to_value(&cal)?,
            "windows": windows,
            "halves_mean_shape_rms": halves_mean_rms,
            "halves_difference_rms": halves_difference_rms,
        }));
    }
    let record = json!({
        "bench": "band_shifts",
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
