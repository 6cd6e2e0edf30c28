//! The `cassi` binary end to end: happy paths, reproducibility, and a clear
//! error with exit code 1 (never a panic, never a partial output) for each
//! kind of bad input.

use std::path::{Path, PathBuf};

use cassi_core::optics::{DispersionModel, NoiseModel, SimulationSpec, simulate};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Cube, Mismatch};
use common::{assert_fails, cassi, ok, s};

mod common;

/// A fresh, empty folder for one test.
fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-tests", name)
}

/// Runs `cassi demo` with `extra` flags into a fresh folder; its JSON report.
fn run_demo(name: &str, extra: &[&str]) -> (PathBuf, serde_json::Value) {
    let dir = scratch(name);
    let mut args = vec!["demo", "--out", s(&dir), "--json"];
    args.extend_from_slice(extra);
    let out = cassi(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report = serde_json::from_slice(&out.stdout).expect("--json prints one JSON object");
    (dir, report)
}

/// PSNR of each scenario: (ideal noisy, assumed, corrected, oracle).
fn demo_psnr(report: &serde_json::Value) -> (f64, f64, f64, f64) {
    let scenarios = report["scenarios"].as_array().expect("scenarios listed");
    let psnr = |name: &str| {
        scenarios
            .iter()
            .find(|o| o["scenario"] == name)
            .and_then(|o| o["metrics"]["psnr"].as_f64())
            .unwrap_or_else(|| panic!("no {name} in {scenarios:?}"))
    };
    (
        psnr("ideal-noisy"),
        psnr("assumed"),
        psnr("corrected"),
        psnr("oracle"),
    )
}

#[test]
fn demo_calibrates_a_physical_instrument_with_covering_error_bars() {
    // the default demo: a 4× oversampled, blurred instrument on a sensor of
    // the nominal width, each band's light spread over its width as a
    // continuous spectrum's is, which no operator the calibration fits
    // made; calibrated in the model `cassi calibrate` fits by default
    let (dir, report) = run_demo("demo", &[]);
    assert_eq!(
        report["simulation"]["measurement"]["shape"],
        serde_json::json!([256, 310])
    );
    assert_eq!(report["simulation"]["physical"]["oversample"], 4);
    assert_eq!(report["simulation"]["physical"]["band_spread"], "uniform");
    assert_eq!(report["calibration"]["band_spread"], "uniform");
    assert!(report["measurement_snr_db"].as_f64().unwrap() > 30.0);
    // the true model (blur included) reconstructs clearly better than the
    // nominal one, and self-calibration closes nearly all of the gap
    let (_, assumed, corrected, oracle) = demo_psnr(&report);
    assert!(
        oracle > assumed + 3.0,
        "oracle {oracle} dB vs nominal {assumed} dB"
    );
    assert!(
        corrected > oracle - 0.5,
        "calibrated {corrected} dB vs oracle {oracle} dB"
    );
    assert!(report["recovery_ratio"].as_f64().unwrap() > 0.9);
    // every parameter, the blur included, is estimated with a standard
    // error and a 95 % half-width, and the truth lies within the interval
    // (what its floors are set to cover in 95 % of cases; a standard error
    // covers 68 %, so this one case is not held to 2σ in every parameter)
    let cal = &report["calibration"];
    let truth = &report["simulation"]["simulation"]["mismatch"];
    assert_eq!(truth["blur_sigma_px"], 0.5);
    for key in ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"] {
        let est = cal["parameters"][key].as_f64().unwrap();
        let t = truth[key].as_f64().unwrap();
        let sigma = cal["uncertainty"][key]
            .as_f64()
            .unwrap_or_else(|| panic!("no standard error for {key}: {cal}"));
        assert!(sigma > 0.0, "{key}: stated σ {sigma}");
        let half_width = cal["interval_95"][key]
            .as_f64()
            .unwrap_or_else(|| panic!("no 95 % interval for {key}: {cal}"));
        assert!(
            (est - t).abs() <= half_width && half_width > sigma,
            "{key}: estimate {est}, truth {t}, 95 % ± {half_width}, σ {sigma}"
        );
    }
    // and the pose is within a tenth of a pixel regardless of what it
    // states (0.03 px at stop 58)
    for key in ["dx", "dy"] {
        let err = cal["parameters"][key].as_f64().unwrap() - truth[key].as_f64().unwrap();
        assert!(err.abs() < 0.1, "{key} off by {err}");
    }
    for f in [
        "calibration.json",
        "recon_ideal_rgb.png",
        "recon_assumed_rgb.png",
        "recon_corrected_rgb.png",
        "recon_oracle_rgb.png",
        "report.md",
        "figures/qualitative.png",
        "figures/psnr_by_method.png",
        "measurement.npy",
        "measurement.json",
        "measurement.png",
        "scene.npy",
        "mask.npy",
        "scene_rgb.png",
        "mask.png",
    ] {
        assert!(dir.join(f).is_file(), "missing {f}");
    }
}

#[test]
fn demo_on_the_rounded_operator_recovers_the_paper_mismatch() {
    // the inverse-crime variant: the rounded operator makes the snapshot
    let (dir, report) = run_demo("demo-rounded", &["--instrument", "rounded"]);
    assert_eq!(
        report["simulation"]["measurement"]["shape"],
        serde_json::json!([256, 311])
    );
    let (ideal, assumed, corrected, oracle) = demo_psnr(&report);
    assert!(
        oracle > assumed + 3.0,
        "oracle {oracle} dB vs nominal {assumed} dB"
    );
    assert!(oracle > 15.0, "oracle GAP-TV only {oracle} dB");
    assert!(
        ideal > assumed + 3.0,
        "ideal {ideal} dB vs nominal {assumed} dB"
    );
    assert!(
        corrected > oracle - 0.5,
        "calibrated {corrected} dB vs oracle {oracle} dB"
    );
    assert!(report["recovery_ratio"].as_f64().unwrap() > 0.9);
    let est = &report["calibration"]["parameters"];
    assert!((est["dx"].as_f64().unwrap() - 1.5).abs() < 0.1, "{est}");
    assert!((est["dy"].as_f64().unwrap() - 1.0).abs() < 0.1, "{est}");
    assert!(
        (est["theta_deg"].as_f64().unwrap() - 0.3).abs() < 0.1,
        "{est}"
    );
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("measurement.json")).unwrap()).unwrap();
    assert_eq!(sidecar["simulation"]["mismatch"]["theta_deg"], 0.3);
    assert_eq!(sidecar["simulation"]["model"], "rounded");
    assert!(sidecar["physical"].is_null());
}

#[test]
fn simulate_reproduces_the_library_and_itself() {
    let dir = scratch("simulate");
    let meas = dir.join("meas.npy");
    let args = [
        "simulate",
        "--synthetic",
        "--size",
        "48",
        "--bands",
        "8",
        "--scene-seed",
        "3",
        "--random-mask",
        "--mask-seed",
        "4",
        "--dx",
        "-0.7",
        "--dy",
        "1.2",
        "--theta",
        "0.4",
        "--a1",
        "2.1",
        "--alpha",
        "-0.5",
        "--model",
        "subpixel",
        "--noise-seed",
        "9",
        "-o",
        s(&meas),
        "--quiet",
    ];
    let out = cassi(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.stdout.is_empty() && out.stderr.is_empty(),
        "--quiet printed something"
    );
    let first = std::fs::read(&meas).unwrap();
    assert!(cassi(&args).status.success());
    assert_eq!(
        first,
        std::fs::read(&meas).unwrap(),
        "same arguments, different bytes"
    );

    // the file holds exactly what the library computes
    let wavelengths = cassi_core::Instrument::with_bands(8, 2.0)
        .unwrap()
        .wavelengths_nm;
    let scene = synthetic_scene(&SceneSpec {
        rows: 48,
        cols: 48,
        wavelengths_nm: wavelengths,
        seed: 3,
    })
    .unwrap();
    let mask = random_binary_mask(48, 48, 0.5, 4).unwrap();
    let spec = SimulationSpec {
        mismatch: Mismatch {
            dx: -0.7,
            dy: 1.2,
            theta_deg: 0.4,
            a1: 2.1,
            alpha_deg: -0.5,
            ..Mismatch::nominal(2.0)
        },
        model: DispersionModel::Subpixel,
        noise: Some(NoiseModel {
            seed: 9,
            ..NoiseModel::default()
        }),
    };
    let want = simulate(&scene, &mask, &spec).unwrap();
    assert_eq!(cassi_io::load_frame(&meas, None).unwrap(), want);

    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("meas.json")).unwrap()).unwrap();
    let back: SimulationSpec = serde_json::from_value(sidecar["simulation"].clone()).unwrap();
    assert_eq!(back, spec, "the sidecar does not record the simulation");

    let info = cassi(&["info", s(&meas)]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(info.status.success() && text.contains("48×63"), "{text}");
}

fn write_scene(path: &Path, cube: &Cube) {
    cassi_io::save_cube(path, cube, "scene").unwrap();
}

#[test]
fn missing_truncated_and_corrupt_files_are_clear_errors() {
    let dir = scratch("bad-files");
    let out = dir.join("out.npy");
    assert_fails(
        &[
            "simulate",
            "--scene",
            s(&dir.join("nope.npy")),
            "--random-mask",
            "-o",
            s(&out),
        ],
        &["nope.npy", "no such file"],
        &out,
    );

    let good = dir.join("good.npy");
    write_scene(&good, &Cube::zeros(4, 16, 16));
    let bytes = std::fs::read(&good).unwrap();
    let truncated = dir.join("truncated.npy");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    assert_fails(
        &[
            "simulate",
            "--scene",
            s(&truncated),
            "--random-mask",
            "-o",
            s(&out),
        ],
        &["truncated.npy", "truncated"],
        &out,
    );

    let garbage = dir.join("garbage.mat");
    std::fs::write(
        &garbage,
        b"this is not a MAT-file at all, just some text that goes on",
    )
    .unwrap();
    assert_fails(&["info", s(&garbage)], &["garbage.mat"], &out);
}

#[test]
fn unknown_variable_lists_what_the_file_holds() {
    let dir = scratch("bad-var");
    let scene = dir.join("scene.npz");
    write_scene(&scene, &Cube::zeros(4, 16, 16));
    let out = dir.join("out.npy");
    assert_fails(
        &[
            "simulate",
            "--scene",
            s(&scene),
            "--scene-var",
            "cube",
            "--random-mask",
            "-o",
            s(&out),
        ],
        &["scene.npz", "'cube'", "scene"],
        &out,
    );
}

#[test]
fn wrong_dimensions_and_size_mismatch_name_both_shapes() {
    let dir = scratch("bad-shape");
    let out = dir.join("out.npy");
    let flat = dir.join("flat.npy");
    cassi_io::save_array(&flat, "flat", &[16, 16], &[0.0; 256]).unwrap();
    assert_fails(
        &[
            "simulate",
            "--scene",
            s(&flat),
            "--random-mask",
            "-o",
            s(&out),
        ],
        &["flat.npy", "16×16", "3-D"],
        &out,
    );

    let scene = dir.join("scene.npy");
    write_scene(&scene, &Cube::zeros(4, 16, 16));
    let mask = dir.join("mask.npy");
    cassi_io::save_array(&mask, "mask", &[16, 20], &[1.0; 320]).unwrap();
    assert_fails(
        &[
            "simulate",
            "--scene",
            s(&scene),
            "--mask",
            s(&mask),
            "-o",
            s(&out),
        ],
        &["16×16", "16×20"],
        &out,
    );
}

#[test]
fn non_finite_values_are_located() {
    let dir = scratch("nan");
    let out = dir.join("out.npy");
    let scene = dir.join("scene.npy");
    let mut data = vec![0.5f32; 4 * 16 * 16];
    data[16 * 16 + 3 * 16 + 5] = f32::NAN; // band 1, row 3, col 5
    cassi_io::save_array(&scene, "scene", &[4, 16, 16], &data).unwrap();
    assert_fails(
        &[
            "simulate",
            "--scene",
            s(&scene),
            "--random-mask",
            "-o",
            s(&out),
        ],
        &["scene.npy", "NaN"],
        &out,
    );
}

#[test]
fn absurd_parameters_are_refused() {
    let dir = scratch("absurd");
    let out = dir.join("out.npy");
    let base = [
        "simulate",
        "--synthetic",
        "--size",
        "16",
        "--random-mask",
        "-o",
    ];
    let cases: [(&[&str], &[&str]); 6] = [
        (&["--theta", "46"], &["theta_deg", "45"]),
        (&["--a1", "0"], &["a1", "between 0.001 and 1000"]),
        (&["--a1", "-2"], &["a1"]),
        (&["--bands", "0"], &["bands"]),
        (&["--alpha", "90"], &["alpha_deg"]),
        (&["--photon-peak", "-1"], &["photon_peak"]),
    ];
    for (extra, needles) in cases {
        let mut args: Vec<&str> = base.to_vec();
        args.push(s(&out));
        args.extend_from_slice(extra);
        assert_fails(&args, needles, &out);
    }
    assert_fails(
        &[
            "simulate",
            "--synthetic",
            "--random-mask",
            "-o",
            s(&dir.join("out.txt")),
        ],
        &["out.txt", ".npy"],
        &dir.join("out.txt"),
    );
}

#[test]
fn an_eight_bit_mask_is_refused_with_advice() {
    let dir = scratch("mask255");
    let out = dir.join("out.npy");
    let mask = dir.join("mask.npy");
    cassi_io::save_array(&mask, "mask", &[16, 16], &[255.0; 256]).unwrap();
    assert_fails(
        &[
            "simulate",
            "--synthetic",
            "--size",
            "16",
            "--mask",
            s(&mask),
            "-o",
            s(&out),
        ],
        &["255"],
        &out,
    );
}

#[test]
fn calibrate_recovers_the_simulated_mismatch_and_feeds_reconstruct() {
    let dir = scratch("calibrate");
    let meas = dir.join("meas.npy");
    let sim = [
        "simulate",
        "--synthetic",
        "--size",
        "96",
        "--bands",
        "8",
        "--random-mask",
        "--dx",
        "1.3",
        "--dy",
        "-0.8",
        "--theta",
        "0.35",
        "--no-noise",
        "-o",
        s(&meas),
        "--quiet",
    ];
    assert!(cassi(&sim).status.success());
    // the random mask is regenerated from its seed for calibrate/reconstruct
    let mask = dir.join("mask.npy");
    cassi_io::save_frame(&mask, &random_binary_mask(96, 96, 0.5, 1).unwrap(), "mask").unwrap();
    // both presets, each from its own JSON (the paper's grids and Adam stages
    // run in a few seconds at this size); each band a point, as the
    // sidecar of the rounded operator that made the data records
    for preset in ["paper", "default"] {
        let calib = dir.join(format!("calib_{preset}.json"));
        let out = cassi(&[
            "calibrate",
            s(&meas),
            "--mask",
            s(&mask),
            "--preset",
            preset,
            "-o",
            s(&calib),
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let cal: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&calib).unwrap()).unwrap();
        assert_eq!(cal["preset"], preset);
        let p = &cal["parameters"];
        assert!(
            (p["dx"].as_f64().unwrap() - 1.3).abs() < 0.1,
            "{preset}: {p}"
        );
        assert!(
            (p["dy"].as_f64().unwrap() + 0.8).abs() < 0.1,
            "{preset}: {p}"
        );
        assert!(
            (p["theta_deg"].as_f64().unwrap() - 0.35).abs() < 0.15,
            "{preset}: {p}"
        );
    }
    let calib = dir.join("calib_default.json");
    let cal: serde_json::Value = serde_json::from_slice(&std::fs::read(&calib).unwrap()).unwrap();
    let cube = dir.join("cube.npy");
    let out = cassi(&[
        "reconstruct",
        s(&meas),
        "--mask",
        s(&mask),
        "--calibration",
        s(&calib),
        "-o",
        s(&cube),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("cube.json")).unwrap()).unwrap();
    // the calibrated model's operator: the reported parameters, σ the
    // blur pass's (since stop 63; the pass started within its range here)
    assert!(
        cal.get("model_blur_sigma_px").is_none(),
        "the default reconstructs with the reported σ"
    );
    assert_eq!(report["model_parameters"], cal["parameters"]);
}

/// `cassi simulate` of the 64×64, 8-band synthetic scene through the
/// random mask (seed 1) into `out`, with `extra` flags.
fn simulate_64(out: &Path, extra: &[&str]) {
    let mut args = vec![
        "simulate",
        "--synthetic",
        "--size",
        "64",
        "--bands",
        "8",
        "--random-mask",
        "-o",
        s(out),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    ok(&cassi(&args));
}

/// `cassi combine`: two snapshots' calibration files → their mean, the
/// snapshots and their agreement, read back by `reconstruct`; a file that
/// is a combination, no calibration, or the output itself is refused by
/// name, nothing written.
#[test]
fn combine_averages_snapshots_and_refuses_what_is_not_one() {
    let dir = scratch("combine");
    let (meas, mask) = (dir.join("meas.npy"), dir.join("mask.npy"));
    simulate_64(&meas, &["--dx", "0.7", "--no-noise"]);
    cassi_io::save_frame(&mask, &random_binary_mask(64, 64, 0.5, 1).unwrap(), "mask").unwrap();
    let first = dir.join("first.json");
    ok(&cassi(&[
        "calibrate",
        s(&meas),
        "--mask",
        s(&mask),
        "--model",
        "rounded",
        "-o",
        s(&first),
        "--quiet",
    ]));
    // a second snapshot's answer: the first's, dx 0.2 px further
    let mut other: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&first).unwrap()).unwrap();
    let dx = other["parameters"]["dx"].as_f64().unwrap();
    other["parameters"]["dx"] = serde_json::json!(dx + 0.2);
    let second = dir.join("second.json");
    std::fs::write(&second, serde_json::to_vec(&other).unwrap()).unwrap();
    let both = dir.join("both.json");
    let out = cassi(&["combine", s(&first), s(&second), "-o", s(&both)]);
    ok(&out);
    let text =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("combined (2 snapshots)"), "{text}");
    let cal: serde_json::Value = serde_json::from_slice(&std::fs::read(&both).unwrap()).unwrap();
    assert_eq!(cal["format"], "cassi-calibration");
    assert!((cal["parameters"]["dx"].as_f64().unwrap() - (dx + 0.1)).abs() < 1e-12);
    assert_eq!(cal["snapshots"]["parameters"].as_array().unwrap().len(), 2);
    assert_eq!(cal["stages"].as_array().unwrap().len(), 2);
    let cube = dir.join("cube.npy");
    ok(&cassi(&[
        "reconstruct",
        s(&meas),
        "--mask",
        s(&mask),
        "--calibration",
        s(&both),
        "--iterations",
        "3",
        "-o",
        s(&cube),
        "--quiet",
    ]));
    let refused = dir.join("refused.json");
    assert_fails(
        &["combine", s(&first), s(&both), "-o", s(&refused)],
        &["both.json", "is itself a combination"],
        &refused,
    );
    assert_fails(
        &[
            "combine",
            s(&first),
            s(&dir.join("meas.json")),
            "-o",
            s(&refused),
        ],
        &["meas.json", "not a cassi-calibration"],
        &refused,
    );
    let before = std::fs::read(&second).unwrap();
    let out = cassi(&["combine", s(&first), s(&second), "-o", s(&second)]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read(&second).unwrap(),
        before,
        "the input was overwritten"
    );
}

/// `cassi combine --joint`: two snapshots of one instrument (different
/// scenes; the 4× oversampled simulator) calibrated by the default, their
/// combination refitted on both measurements as one: the answer moves from
/// the combination (kept in the file), σ and the error bars stay the
/// combination's, the joint passes are stages. A measurement count that
/// is not the calibrations', or calibrations of a model the scene fit does
/// not run, are refused before any work, nothing written.
#[test]
fn combine_refits_the_snapshots_jointly_on_their_measurements() {
    let dir = scratch("combine-joint");
    let mask = dir.join("mask.npy");
    cassi_io::save_frame(&mask, &random_binary_mask(64, 64, 0.5, 1).unwrap(), "mask").unwrap();
    let mut meas = Vec::new();
    let mut cals = Vec::new();
    for seed in ["1", "2"] {
        let m = dir.join(format!("meas{seed}.npy"));
        simulate_64(
            &m,
            &[
                "--scene-seed",
                seed,
                "--noise-seed",
                seed,
                "--oversample",
                "4",
                "--blur",
                "0.4",
                "--dx",
                "0.6",
                "--dy",
                "-0.3",
                "--a1",
                "2.02",
            ],
        );
        let c = dir.join(format!("cal{seed}.json"));
        ok(&cassi(&[
            "calibrate",
            s(&m),
            "--mask",
            s(&mask),
            "-o",
            s(&c),
            "--quiet",
        ]));
        meas.push(m);
        cals.push(c);
    }
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let plain = dir.join("plain.json");
    ok(&cassi(&[
        "combine",
        s(&cals[0]),
        s(&cals[1]),
        "-o",
        s(&plain),
        "--quiet",
    ]));
    let joint = dir.join("joint.json");
    let out = cassi(&[
        "combine",
        s(&cals[0]),
        s(&cals[1]),
        "-o",
        s(&joint),
        "--joint",
        s(&meas[0]),
        s(&meas[1]),
        "--mask",
        s(&mask),
    ]);
    ok(&out);
    let text =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("joint fit (one ψ"), "{text}");
    let (plain, joint_cal) = (read(&plain), read(&joint));
    assert_eq!(
        joint_cal["snapshots"]["joint_fit_from"],
        plain["parameters"]
    );
    assert_ne!(joint_cal["parameters"]["dx"], plain["parameters"]["dx"]);
    assert_eq!(
        joint_cal["parameters"]["blur_sigma_px"],
        plain["parameters"]["blur_sigma_px"]
    );
    assert_eq!(joint_cal["uncertainty"], plain["uncertainty"]);
    let stages = joint_cal["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 4);
    assert!(
        stages[3]["name"]
            .as_str()
            .unwrap()
            .starts_with("joint fit's fine pass")
    );
    let dx = joint_cal["parameters"]["dx"].as_f64().unwrap();
    assert!((dx - 0.6).abs() < 0.15, "joint dx {dx}");
    // refused before any work
    let refused = dir.join("refused.json");
    let joint_args = |cals: &[&PathBuf], meas: &[&PathBuf]| -> Vec<String> {
        let mut args = vec!["combine".to_string()];
        args.extend(cals.iter().map(|p| s(p).to_string()));
        args.extend(["-o", s(&refused), "--joint"].map(String::from));
        args.extend(meas.iter().map(|p| s(p).to_string()));
        args.extend(["--mask", s(&mask)].map(String::from));
        args
    };
    let refuses = |args: Vec<String>, needle: &str| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_fails(&args, &[needle], &refused);
    };
    refuses(
        joint_args(&[&cals[0], &cals[1]], &[&meas[0], &meas[0], &meas[1]]),
        "3 measurements for 2 calibrations",
    );
    let rounded: Vec<PathBuf> = (0..2)
        .map(|i| {
            let c = dir.join(format!("rounded{i}.json"));
            ok(&cassi(&[
                "calibrate",
                s(&meas[i]),
                "--mask",
                s(&mask),
                "--model",
                "rounded",
                "-o",
                s(&c),
                "--quiet",
            ]));
            c
        })
        .collect();
    refuses(
        joint_args(&[&rounded[0], &rounded[1]], &[&meas[0], &meas[1]]),
        "Rounded model does not run",
    );
}

/// Sharded runs merged give the study one process makes: every score and
/// parameter the same (only timings differ), the report and figures
/// written; a merge before every shard has finished names the missing one.
#[test]
fn eval_shards_merge_into_the_one_process_study() {
    let dir = scratch("eval-shards");
    let (whole, sharded) = (dir.join("whole"), dir.join("sharded"));
    let base = [
        "eval",
        "--synthetic",
        "--count",
        "3",
        "--size",
        "64",
        "--iterations",
        "15",
        "--quiet",
    ];
    let run = |extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        cassi(&args)
    };
    ok(&run(&["-o", s(&whole)]));
    ok(&run(&["-o", s(&sharded), "--shard", "1/2"]));
    let early = run(&["-o", s(&sharded), "--merge", "2"]);
    assert!(!early.status.success());
    let e = String::from_utf8_lossy(&early.stderr);
    assert!(e.contains("shard 0/2") && e.contains("synthetic_0"), "{e}");
    assert!(
        !sharded.join("report.md").exists(),
        "a failed merge wrote a report"
    );
    ok(&run(&["-o", s(&sharded), "--shard", "0/2"]));
    ok(&run(&["-o", s(&sharded), "--merge", "2"]));
    // scores and parameters equal; the last column (seconds) is timing
    let without_timing = |path: std::path::PathBuf| -> Vec<String> {
        std::fs::read_to_string(&path)
            .unwrap()
            .lines()
            .map(|l| l.rsplit_once(',').map_or(l, |(head, _)| head).to_string())
            .collect()
    };
    assert_eq!(
        without_timing(whole.join("outcomes.csv")),
        without_timing(sharded.join("outcomes.csv"))
    );
    for f in [
        "parameters.csv",
        "report.md",
        "figures/qualitative.png",
        "scenes/synthetic_2.json",
    ] {
        assert!(sharded.join(f).is_file(), "{f} missing after the merge");
    }
    assert_eq!(
        without_timing(whole.join("parameters.csv")),
        without_timing(sharded.join("parameters.csv"))
    );
    // sweeps are not sharded
    let refused = run(&["-o", s(&sharded), "--shard", "0/2", "--ablation"]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("not sharded"));
}

/// The sweeps' studies run in folders of their own under --out; their
/// scene records join the output set with the rest (they used to fail to
/// write: their nested folders were never created).
#[test]
fn eval_sweeps_write_their_studies_and_tables() {
    let dir = scratch("eval-sweeps");
    let out = dir.join("study");
    let res = cassi(&[
        "eval",
        "--synthetic",
        "--size",
        "64",
        "--iterations",
        "15",
        "--sensitivity",
        "0.5,1",
        "--ablation",
        "-o",
        s(&out),
    ]);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    for scale in ["0.5", "1"] {
        let f = out.join(format!(
            "sensitivity/default_scale{scale}/scenes/synthetic_0.json"
        ));
        assert!(f.is_file(), "{} missing", f.display());
    }
    assert!(
        !out.join("sensitivity/default_scale0.5/.pending").exists(),
        "a sweep's pending folder was left behind"
    );
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains("## Sensitivity to the mismatch size"),
        "{report}"
    );
    assert!(
        report.contains("## Ablation of the calibration pipeline"),
        "{report}"
    );
}

#[test]
fn eval_writes_the_study_and_resumes_without_rerunning() {
    let dir = scratch("eval");
    let out = dir.join("study");
    let args = [
        "eval",
        "--synthetic",
        "--count",
        "2",
        "--size",
        "64",
        "--iterations",
        "15",
        "--methods",
        "gap-tv",
        "-o",
        s(&out),
    ];
    let first = cassi(&args);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    for f in [
        "report.md",
        "summary.json",
        "outcomes.csv",
        "parameters.csv",
        "scenes/synthetic_0.json",
        "scenes/synthetic_1.json",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("III Corrected") && report.contains("Metric definitions"));
    // 2 scenes × 5 scenarios + header
    let csv = std::fs::read_to_string(out.join("outcomes.csv")).unwrap();
    assert_eq!(csv.lines().count(), 11, "{csv}");
    let stamp = std::fs::metadata(out.join("scenes/synthetic_0.json"))
        .unwrap()
        .modified()
        .unwrap();
    let mut resumed = args.to_vec();
    resumed.push("--resume");
    let again = cassi(&resumed);
    assert!(again.status.success());
    assert!(String::from_utf8_lossy(&again.stdout).contains("earlier run"));
    let stamp2 = std::fs::metadata(out.join("scenes/synthetic_0.json"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(stamp, stamp2, "a finished scene was rerun");
    // a different study in the same folder is not mistaken for this one
    let mut other = resumed.clone();
    other.extend(["--dx", "0.5"]);
    let third = cassi(&other);
    assert!(third.status.success());
    let third_out = String::from_utf8_lossy(&third.stdout);
    assert!(
        !third_out.contains("result from an earlier run"),
        "{third_out}"
    );
    assert!(
        third_out.contains("recomputed: the settings differ"),
        "{third_out}"
    );
    assert_fails(
        &["eval", "--scenes", "/nonexistent/scenes", "--mask", "m.npy"],
        &["/nonexistent/scenes"],
        &dir.join("none"),
    );
}

/// The learned methods refuse solver flags (networks) and need --weights,
/// whatever the build, saying where official weights come from; without
/// `--features nets` they say how to get them.
#[test]
fn network_methods_check_their_flags() {
    let dir = scratch("nets-flags");
    let out = dir.join("cube.npy");
    let (y, m, w) = (dir.join("y.npy"), dir.join("mask.npy"), dir.join("w.pth"));
    let base = ["reconstruct", s(&y), "--mask", s(&m), "-o", s(&out)];
    let with = |extra: &[&'static str]| -> Vec<String> {
        base.iter()
            .map(|a| a.to_string())
            .chain(extra.iter().map(|a| a.to_string()))
            .collect()
    };
    let run = |args: Vec<String>, needles: &[&str]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_fails(&args, needles, &out);
    };
    run(
        with(&["--method", "mst-s"]),
        &["needs --weights", "caiyuanhao1998/MST"],
    );
    run(
        with(&["--method", "pnp-hsicnn"]),
        &["needs --weights", "zsm1211/PnP-CASSI", "deep_denoiser.pth"],
    );
    run(
        with(&[
            "--method",
            "hdnet",
            "--weights",
            "w.pth",
            "--iterations",
            "5",
        ]),
        &["--iterations does not apply to --method hdnet"],
    );
    run(
        with(&["--method", "gap-tv", "--weights", "w.pth"]),
        &["--weights is for the learned methods"],
    );
    if cfg!(not(feature = "nets")) {
        for method in ["mst-l", "pnp-hsicnn"] {
            let mut args = with(&["--weights"]);
            args.extend([s(&w).to_string(), "--method".into(), method.into()]);
            run(
                args,
                &["built without the deep networks", "--features nets"],
            );
        }
        // eval: the same advice before any work
        assert_fails(
            &[
                "eval",
                "--synthetic",
                "--methods",
                "gap-tv,mst-s",
                "-o",
                s(&dir.join("study")),
            ],
            &["--methods mst-s", "--features nets"],
            &dir.join("study"),
        );
    }
}

/// `cassi eval` with learned methods: weights are required (with where to
/// get them), checked before any scene, and shapes a network cannot take
/// are refused with both shapes.
#[cfg(feature = "nets")]
#[test]
fn eval_checks_learned_methods_before_running() {
    let dir = scratch("eval-nets-errors");
    let study = dir.join("study");
    let eval = |extra: &[&str]| {
        let mut args = vec!["eval", "--synthetic", "--size", "64", "-o", s(&study)];
        args.extend_from_slice(extra);
        args.iter().map(|a| a.to_string()).collect::<Vec<_>>()
    };
    let fails = |args: Vec<String>, needles: &[&str]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_fails(&args, needles, &study);
    };
    fails(
        eval(&["--methods", "gap-tv,mst-l"]),
        &[
            "--methods mst-l needs weights",
            "--weights-dir",
            "caiyuanhao1998/MST",
        ],
    );
    fails(
        eval(&["--methods", "pnp-hsicnn", "--weights-dir", s(&dir)]),
        &["deep_denoiser.pth", "zsm1211/PnP-CASSI"],
    );
    fails(
        eval(&["--methods", "hdnet", "--weights", "mst-s=x.pth"]),
        &["--methods does not include mst-s"],
    );
    fails(
        eval(&["--methods", "gap-tv,mst-xl"]),
        &["unknown method 'mst-xl'", "pnp-hsicnn"],
    );
    let garbage = dir.join("mst_s.pth");
    std::fs::write(&garbage, b"not a checkpoint").unwrap();
    fails(
        eval(&["--methods", "mst-s", "--weights-dir", s(&dir)]),
        &["mst_s.pth"],
    );
    let Some(data) = shared_data() else { return };
    fails(
        eval(&[
            "--methods",
            "mst-s",
            "--weights",
            &format!("mst-s={}", s(&data.join("weights/mst_s.pth"))),
        ]),
        &["mst-s takes 256×256", "64×64"],
    );
}

/// `cassi eval` runs a network and PnP-HSICNN next to GAP-TV through all
/// five scenarios (seeded test-vector weights: plumbing, not quality).
#[cfg(feature = "nets")]
#[test]
fn eval_runs_learned_methods_in_every_scenario() {
    let Some(data) = shared_data() else { return };
    let dir = scratch("eval-nets");
    let out = dir.join("study");
    let hdnet = format!(
        "hdnet={}",
        s(&data.join("nets/hdnet/hdnet_seed0.safetensors"))
    );
    let pnp = format!(
        "pnp-hsicnn={}",
        s(&data.join("nets/hsi_sdecnn/hsi_sdecnn_seed0.safetensors"))
    );
    let res = cassi(&[
        "eval",
        "--synthetic",
        "--size",
        "64",
        "--iterations",
        "84",
        "--methods",
        "gap-tv,hdnet,pnp-hsicnn",
        "--weights",
        &hdnet,
        "--weights",
        &pnp,
        "-o",
        s(&out),
        "--quiet",
    ]);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let csv = std::fs::read_to_string(out.join("outcomes.csv")).unwrap();
    for method in ["gap-tv", "hdnet", "pnp-hsicnn"] {
        assert_eq!(
            csv.lines().filter(|l| l.contains(method)).count(),
            5,
            "{method}: {csv}"
        );
    }
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("scenes/synthetic_0.json")).unwrap())
            .unwrap();
    let methods = &record["study"]["methods"];
    assert_eq!(methods[1]["method"], "hdnet");
    assert!(
        methods[1]["weights"]
            .as_str()
            .unwrap()
            .ends_with("hdnet_seed0.safetensors")
    );
    assert_eq!(methods[2]["iterations"], 84);
    // HDNet never sees the mask: Assumed, Corrected and Oracle coincide
    let psnr = |scenario: &str| {
        record["result"]["outcomes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["method"] == "hdnet" && o["scenario"] == scenario)
            .unwrap()["metrics"]["psnr"]
            .as_f64()
            .unwrap()
    };
    assert_eq!(psnr("assumed"), psnr("oracle"));
    assert_eq!(psnr("assumed"), psnr("corrected"));
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("Learned methods"), "{report}");
}

/// ../shared/data (or $CASSI_SHARED_DATA) when it holds the network files;
/// `None` after a note (see `cassi_io::shared_data`).
#[cfg(feature = "nets")]
fn shared_data() -> Option<PathBuf> {
    cassi_io::shared_data::for_test(&["nets"])
}

/// With `--features nets`: the official MST-S weights on the reference
/// measurement give PSNR 26.79 dB (the README of shared/data/nets).
#[cfg(feature = "nets")]
#[test]
fn mst_s_reconstructs_the_reference_measurement() {
    let Some(data) = shared_data() else { return };
    let dir = scratch("nets-mst-s");
    let out = dir.join("cube.npy");
    let common = data.join("nets/common");
    let res = cassi(&[
        "reconstruct",
        s(&common.join("y.npy")),
        "--mask",
        s(&common.join("mask.npy")),
        "--method",
        "mst-s",
        "--weights",
        s(&data.join("weights/mst_s.pth")),
        "--truth",
        s(&common.join("cube.npy")),
        "-o",
        s(&out),
        "--json",
    ]);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    let psnr = report["metrics"]["psnr"].as_f64().unwrap();
    assert!((psnr - 26.79).abs() < 0.01, "PSNR {psnr}");
    assert!(out.with_extension("png").exists());
}

/// `--calibration` reaches the networks as the mask pose: the report
/// carries it, a1/α are noted as unused, and the cube differs from the
/// nominal one (the reference measurement is nominal, so it gets worse).
#[cfg(feature = "nets")]
#[test]
fn mst_s_takes_a_calibrated_mask() {
    let Some(data) = shared_data() else { return };
    let dir = scratch("nets-mst-s-calibrated");
    let common = data.join("nets/common");
    let calib = dir.join("calib.json");
    std::fs::write(
        &calib,
        r#"{"parameters": {"dx": 1.5, "dy": 1.0, "theta_deg": 0.3, "a1": 2.04, "alpha_deg": 0.0}}"#,
    )
    .unwrap();
    let run = |out: &Path, calibration: Option<&Path>| {
        let mut args = vec![
            "reconstruct".to_string(),
            s(&common.join("y.npy")).into(),
            "--mask".into(),
            s(&common.join("mask.npy")).into(),
            "--method".into(),
            "mst-s".into(),
            "--weights".into(),
            s(&data.join("weights/mst_s.pth")).into(),
            "--truth".into(),
            s(&common.join("cube.npy")).into(),
            "-o".into(),
            s(out).into(),
            "--json".into(),
        ];
        if let Some(c) = calibration {
            args.extend(["--calibration".into(), s(c).into()]);
        }
        let res = std::process::Command::new(env!("CARGO_BIN_EXE_cassi"))
            .args(&args)
            .output()
            .unwrap();
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        let report: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
        report
    };
    let nominal = run(&dir.join("nominal.npy"), None);
    let posed = run(&dir.join("posed.npy"), Some(&calib));
    assert_eq!(nominal["mask_pose"]["dx"], 0.0);
    assert!(nominal["unused_dispersion"].is_null());
    assert_eq!(posed["mask_pose"]["dx"], 1.5);
    assert_eq!(posed["mask_pose"]["theta_deg"], 0.3);
    assert_eq!(posed["unused_dispersion"]["a1"], 2.04);
    let (pn, pp) = (
        nominal["metrics"]["psnr"].as_f64().unwrap(),
        posed["metrics"]["psnr"].as_f64().unwrap(),
    );
    assert!(
        pp < pn - 1.0,
        "a moved mask should hurt on a nominal measurement: {pp} vs {pn}"
    );
}

/// PnP-HSICNN from the command line with the seeded denoiser weights: the
/// schedule in the report (85 iterations: 83 TV + 2 network), the
/// calibration's whole model used.
#[cfg(feature = "nets")]
#[test]
fn pnp_hsicnn_runs_its_schedule_from_the_command_line() {
    let Some(data) = shared_data() else { return };
    let dir = scratch("nets-pnp");
    let meas = dir.join("meas.npy");
    let sim = cassi(&[
        "simulate",
        "--synthetic",
        "--size",
        "24",
        "--bands",
        "8",
        "--random-mask",
        "--dx",
        "0.5",
        "--no-noise",
        "-o",
        s(&meas),
        "--quiet",
    ]);
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    // the random mask is regenerated from its seed
    let mask = dir.join("mask.npy");
    cassi_io::save_frame(&mask, &random_binary_mask(24, 24, 0.5, 1).unwrap(), "mask").unwrap();
    let out = dir.join("cube.npy");
    let res = cassi(&[
        "reconstruct",
        s(&meas),
        "--mask",
        s(&mask),
        "--calibration",
        s(&meas.with_extension("json")),
        "--method",
        "pnp-hsicnn",
        "--weights",
        s(&data.join("nets/hsi_sdecnn/hsi_sdecnn_seed0.safetensors")),
        "--iterations",
        "85",
        "-o",
        s(&out),
        "--json",
    ]);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    assert_eq!(report["iterations"], 85);
    assert_eq!(report["tv_iterations"], 83);
    assert_eq!(report["network_iterations"], 2);
    assert_eq!(report["model_parameters"]["dx"], 0.5);
    assert_eq!(report["params"]["schedule"]["warmup"], 83);
    assert!(out.is_file() && out.with_extension("png").is_file());
}
