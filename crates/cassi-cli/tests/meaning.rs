//! Meaningless inputs and absurd parameters (issue #12, items 4–7): refused
//! before any work with a message that names the file or flag and the
//! arithmetic, or accepted with a stated warning where they are legitimate;
//! and `eval --resume` that cannot mix studies.

mod common;

use std::path::{Path, PathBuf};

use cassi_core::Frame;
use common::{assert_fails, cassi, cassi_env, ok, s, scratch};

fn dir(name: &str) -> PathBuf {
    scratch("meaning", name)
}

fn save(path: &Path, rows: usize, cols: usize, f: impl Fn(usize, usize) -> f32) {
    let data = (0..rows * cols).map(|i| f(i / cols, i % cols)).collect();
    cassi_io::save_frame(path, &Frame::from_vec(rows, cols, data).unwrap(), "x").unwrap();
}

/// A 32×32 4-band simulation (with its sidecar) and its random mask.
fn simulated(d: &Path) -> (PathBuf, PathBuf) {
    let meas = simulated_as(d, "m.npy", &[]);
    let mask = d.join("mask.npy");
    // the mask the simulation used, as a file
    let m = cassi_core::synth::random_binary_mask(32, 32, 0.5, 1).unwrap();
    cassi_io::save_frame(&mask, &m, "mask").unwrap();
    (meas, mask)
}

/// `cassi simulate` of the same scene and mask into `d/name`, with
/// `extra` flags.
fn simulated_as(d: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let meas = d.join(name);
    let mut args = vec![
        "simulate",
        "--synthetic",
        "--size",
        "32",
        "--bands",
        "4",
        "--random-mask",
        "-o",
        s(&meas),
        "-q",
    ];
    args.extend_from_slice(extra);
    ok(&cassi(&args));
    meas
}

#[test]
fn measurements_without_light_and_masks_without_code_are_refused() {
    let d = dir("light");
    let (_, mask) = simulated(&d);
    let out = d.join("c.json");
    // 32 rows, 32 + 27·2 columns: fits the default 28 bands
    let zero = d.join("zero.npy");
    save(&zero, 32, 86, |_, _| 0.0);
    assert_fails(
        &["calibrate", s(&zero), "--mask", s(&mask), "-o", s(&out)],
        &["zero.npy", "no light", "every value is 0"],
        &out,
    );
    let negative = d.join("negative.npy");
    save(&negative, 32, 86, |r, c| -1.0 - (r + c) as f32);
    assert_fails(
        &["calibrate", s(&negative), "--mask", s(&mask), "-o", s(&out)],
        &["negative.npy", "≤ 0"],
        &out,
    );
    let signed = d.join("signed.npy");
    save(
        &signed,
        32,
        86,
        |r, c| if (r + c) % 2 == 0 { 1.0 } else { -1.0 },
    );
    assert_fails(
        &[
            "reconstruct",
            s(&signed),
            "--mask",
            s(&mask),
            "-o",
            s(&d.join("r.npy")),
        ],
        &["signed.npy", "down to -1"],
        &d.join("r.npy"),
    );
    let light = d.join("light.npy");
    save(&light, 32, 86, |r, c| ((r * 7 + c * 3) % 5) as f32);
    let closed = d.join("closed.npy");
    save(&closed, 32, 32, |_, _| 0.0);
    assert_fails(
        &["calibrate", s(&light), "--mask", s(&closed), "-o", s(&out)],
        &["closed.npy", "every pixel is closed"],
        &out,
    );
    assert_fails(
        &[
            "simulate",
            "--synthetic",
            "--size",
            "32",
            "--mask",
            s(&closed),
            "-o",
            s(&d.join("s.npy")),
        ],
        &["closed.npy", "every pixel is closed"],
        &d.join("s.npy"),
    );
    // an all-open mask codes nothing: calibration refuses it, reconstruction
    // warns and goes on
    let open = d.join("open.npy");
    save(&open, 32, 32, |_, _| 1.0);
    assert_fails(
        &["calibrate", s(&light), "--mask", s(&open), "-o", s(&out)],
        &["open.npy", "uncoded"],
        &out,
    );
    let r = cassi(&[
        "reconstruct",
        s(&light),
        "--mask",
        s(&open),
        "--iterations",
        "2",
        "-o",
        s(&d.join("r.npy")),
    ]);
    ok(&r);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(
        stderr.contains("warning: mask") && stderr.contains("nothing is coded"),
        "{stderr}"
    );
}

#[test]
fn band_counts_are_never_guessed() {
    let d = dir("bands");
    let (meas, mask) = simulated(&d);
    let out = d.join("r.npy");
    // the sidecar says 4 bands
    let r = cassi(&[
        "reconstruct",
        s(&meas),
        "--mask",
        s(&mask),
        "--iterations",
        "2",
        "-o",
        s(&out),
    ]);
    ok(&r);
    let said = String::from_utf8_lossy(&r.stdout);
    assert!(
        said.contains("bands: 4 (from the simulation sidecar"),
        "{said}"
    );
    // the issue's case: a 300-column mask and a 311-column measurement is no
    // band count at stride 2 (it was silently 6 bands)
    let wide_mask = d.join("mask300.npy");
    save(&wide_mask, 32, 300, |r, c| ((r * 5 + c * 3) % 2) as f32);
    let m311 = d.join("m311.npy");
    save(&m311, 32, 311, |r, c| ((r + c) % 7) as f32);
    let c = d.join("c.json");
    assert_fails(
        &["calibrate", s(&m311), "--mask", s(&wide_mask), "-o", s(&c)],
        &[
            "m311.npy",
            "311 columns",
            "300-column mask",
            "11 extra columns",
            "--bands",
        ],
        &c,
    );
    // --bands that do not fit the width: the arithmetic is shown
    assert_fails(
        &[
            "calibrate",
            s(&m311),
            "--mask",
            s(&wide_mask),
            "--bands",
            "28",
            "-o",
            s(&c),
        ],
        &["311 columns do not fit --bands 28", "354"],
        &c,
    );
    // a tiny stride turns the extra columns into thousands of bands: refused
    for stride in ["0.01", "0.001"] {
        assert_fails(
            &[
                "calibrate",
                s(&m311),
                "--mask",
                s(&wide_mask),
                "--stride",
                stride,
                "-o",
                s(&c),
            ],
            &["stride"],
            &c,
        );
    }
}

#[test]
fn absurd_sizes_are_refused_before_allocating() {
    let d = dir("sizes");
    let out = d.join("s.npy");
    let synthetic = ["simulate", "--synthetic", "--random-mask", "-o", s(&out)];
    for (extra, needles) in [
        (
            &["--size", "20000"][..],
            &["too large", "--size 20000", "budget"][..],
        ),
        (
            &["--bands", "100000"],
            &["too large", "--bands 100000", "budget"],
        ),
        (
            &["--stride", "0.001"],
            &["stride", "between 0.001 and 1000"],
        ),
        (
            &["--size", "32", "--dx", "1e9"],
            &["dx = 1e9", "mask width (32 px)"],
        ),
    ] {
        let mut args = synthetic.to_vec();
        args.extend_from_slice(extra);
        assert_fails(&args, needles, &out);
    }
    // the budget is configurable: a 64×64×28 scene is 114,688 elements
    let mut args = synthetic.to_vec();
    args.extend(["--size", "64"]);
    let small = cassi_env(&args, &[("CASSI_MAX_ELEMENTS", "100000")]);
    assert_eq!(small.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&small.stderr).contains("budget of 100000"));
    assert!(!out.exists());
    ok(&cassi_env(&args, &[("CASSI_MAX_ELEMENTS", "200000")]));
}

#[test]
fn parameter_files_are_read_by_name_and_range() {
    let d = dir("params");
    let (meas, mask) = simulated(&d);
    let out = d.join("r.npy");
    let named = |fields: &str| format!("{{\"parameters\": {{{fields}}}}}");
    for (name, text, needles) in [
        (
            "positional.json",
            "{\"parameters\": [1, 2, 3, 4, 5]}".to_string(),
            &["positional.json", "named fields", "an array"][..],
        ),
        (
            "huge.json",
            named("\"dx\": 1e308, \"dy\": 0, \"theta_deg\": 0, \"a1\": 2, \"alpha_deg\": 0"),
            &["huge.json", "dx = 1e308", "mask width"],
        ),
        (
            "tiny.json",
            named("\"dx\": 0, \"dy\": 0, \"theta_deg\": 0, \"a1\": 1e-300, \"alpha_deg\": 0"),
            &["tiny.json", "a1 = 1e-300"],
        ),
        (
            "extra.json",
            named("\"dx\": 0, \"dy\": 0, \"theta_deg\": 0, \"a1\": 2, \"alpha_deg\": 0, \"dz\": 1"),
            &["extra.json", "unknown field(s) dz"],
        ),
        (
            "text.json",
            named("\"dx\": \"1\", \"dy\": 0, \"theta_deg\": 0, \"a1\": 2, \"alpha_deg\": 0"),
            &["text.json", "dx must be a number"],
        ),
        (
            "missing.json",
            named("\"dx\": 0, \"dy\": 0, \"theta_deg\": 0, \"alpha_deg\": 0"),
            &["missing.json", "a1 is missing"],
        ),
        (
            "bent.json",
            named(
                "\"dx\": 0, \"dy\": 0, \"theta_deg\": 0, \"a1\": 2, \"alpha_deg\": 0, \"a2\": 0.9",
            ),
            &["bent.json", "a2", "0.5"],
        ),
    ] {
        let file = d.join(name);
        std::fs::write(&file, text).unwrap();
        assert_fails(
            &[
                "reconstruct",
                s(&meas),
                "--mask",
                s(&mask),
                "--calibration",
                s(&file),
                "-o",
                s(&out),
            ],
            needles,
            &out,
        );
    }
}

#[test]
fn eval_flags_that_could_only_fail_later_are_refused_first() {
    let d = dir("eval-flags");
    let out = d.join("study");
    for (extra, needles) in [
        (&["--count", "0"][..], &["--count 0"][..]),
        (&["--size", "8"], &["--size 8", "11×11"]),
        (&["--limit", "0"], &["--limit 0"]),
        (&["--sensitivity=nan"], &["--sensitivity NaN"]),
        (
            &["--size", "16", "--sensitivity", "1,40"],
            &["--sensitivity 40", "mask width"],
        ),
    ] {
        let mut args = vec!["eval", "--synthetic", "-o", s(&out)];
        args.extend_from_slice(extra);
        assert_fails(&args, needles, &out);
    }
}

#[test]
fn eval_resume_recomputes_a_scene_whose_mask_changed() {
    let d = dir("resume-mask");
    let out = d.join("study");
    let (a, b) = (d.join("a.npy"), d.join("b.npy"));
    cassi_io::save_frame(
        &a,
        &cassi_core::synth::random_binary_mask(32, 32, 0.5, 1).unwrap(),
        "m",
    )
    .unwrap();
    cassi_io::save_frame(
        &b,
        &cassi_core::synth::random_binary_mask(32, 32, 0.5, 2).unwrap(),
        "m",
    )
    .unwrap();
    let run = |mask: &Path, resume: bool| {
        let mut args = vec![
            "eval",
            "--synthetic",
            "--size",
            "32",
            "--iterations",
            "3",
            "--mask",
            s(mask),
            "-o",
            s(&out),
        ];
        if resume {
            args.push("--resume");
        }
        let r = cassi(&args);
        ok(&r);
        (
            String::from_utf8_lossy(&r.stdout).into_owned(),
            std::fs::read_to_string(out.join("scenes/synthetic_0.json")).unwrap(),
        )
    };
    let (_, first) = run(&a, false);
    let (said, same) = run(&a, true);
    assert!(said.contains("result from an earlier run"), "{said}");
    assert_eq!(first, same);
    // another mask under the same name: recomputed, and said so
    let (said, other) = run(&b, true);
    assert!(
        said.contains("recomputed: the mask's data differ"),
        "{said}"
    );
    assert!(!said.contains("result from an earlier run"), "{said}");
    assert_ne!(first, other);
}

/// `--calibration` takes a calibration record (current, or as cassi wrote
/// it before records had a header), a simulation sidecar or a bare
/// parameter object; another kind of record or a newer version is refused,
/// naming the file.
/// The model parameters `cassi reconstruct --calibration FILE` reports
/// having used (two GAP-TV iterations).
fn model_parameters(meas: &Path, mask: &Path, calibration: &Path, out: &Path) -> serde_json::Value {
    reconstruction_report(meas, mask, calibration, out)["model_parameters"].clone()
}

/// The report of `cassi reconstruct --calibration FILE` (two GAP-TV
/// iterations).
fn reconstruction_report(
    meas: &Path,
    mask: &Path,
    calibration: &Path,
    out: &Path,
) -> serde_json::Value {
    let run = cassi(&[
        "reconstruct",
        s(meas),
        "--mask",
        s(mask),
        "--calibration",
        s(calibration),
        "--iterations",
        "2",
        "-o",
        s(out),
        "--json",
    ]);
    ok(&run);
    serde_json::from_slice(&run.stdout).unwrap()
}

#[test]
fn calibration_files_are_typed_records_or_parameter_objects() {
    let d = dir("records");
    let (meas, mask) = simulated(&d);
    let out = d.join("r.npy");
    let reconstruct = |calibration: &Path| {
        model_parameters(&meas, &mask, calibration, &out)["dx"]
            .as_f64()
            .unwrap()
    };
    let v0 = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cassi-eval/tests/fixtures/v0");
    assert_eq!(
        reconstruct(&v0.join("calibration.json")),
        1.5000525971892626
    );
    assert_eq!(reconstruct(&v0.join("sidecar.json")), 1.5);
    let bare = d.join("bare.json");
    std::fs::write(
        &bare,
        r#"{"dx": 0.25, "dy": 0, "theta_deg": 0, "a1": 2, "alpha_deg": 0}"#,
    )
    .unwrap();
    assert_eq!(reconstruct(&bare), 0.25);
    // this build's own calibration record
    let cal = d.join("cal.json");
    ok(&cassi(&[
        "calibrate",
        s(&meas),
        "--mask",
        s(&mask),
        "-o",
        s(&cal),
        "-q",
    ]));
    let text = std::fs::read_to_string(&cal).unwrap();
    assert!(text.starts_with("{\n  \"format\": \"cassi-calibration\",\n  \"version\": 1,"));
    reconstruct(&cal);

    let newer = d.join("newer.json");
    std::fs::write(&newer, text.replacen("\"version\": 1", "\"version\": 9", 1)).unwrap();
    let summary = v0.join("summary.json");
    let refused = d.join("refused.npy");
    for (file, needles) in [
        (&newer, &["newer.json", "version 9", "newer cassi"][..]),
        (
            &summary,
            &[
                "summary.json is a cassi-study-summary record",
                "not a calibration",
            ],
        ),
    ] {
        assert_fails(
            &[
                "reconstruct",
                s(&meas),
                "--mask",
                s(&mask),
                "--calibration",
                s(file),
                "-o",
                s(&refused),
            ],
            needles,
            &refused,
        );
    }
}

#[test]
fn a_curved_dispersion_travels_from_the_calibration_to_the_model() {
    let d = dir("curved");
    let (meas, mask) = simulated(&d);
    let out = d.join("r.npy");
    let curved = d.join("curved.json");
    std::fs::write(
        &curved,
        r#"{"dx": 0.25, "dy": 0, "theta_deg": 0, "a1": 2, "alpha_deg": 0, "a2": -0.008}"#,
    )
    .unwrap();
    let used = model_parameters(&meas, &mask, &curved, &out);
    assert_eq!(used["a2"].as_f64(), Some(-0.008));
    // (beyond the guard it is refused: parameter_files_are_read_by_name_and_range)
    // the calibration holds the curvature it is given, and writes it
    let cal = d.join("cal.json");
    let calibrate = |extra: &[&str]| {
        let mut a = vec![
            "calibrate",
            s(&meas),
            "--mask",
            s(&mask),
            "-o",
            s(&cal),
            "-q",
        ];
        a.extend(extra);
        a.into_iter().map(String::from).collect::<Vec<_>>()
    };
    ok(&cassi(
        &calibrate(&["--dispersion-a2", "-0.004"])
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    ));
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap();
    assert_eq!(record["parameters"]["a2"].as_f64(), Some(-0.004));
    // a curved dispersion also runs the fits from the nominal a1
    let stages = record["stages"].as_array().expect("stages");
    let restart = cassi_core::calib::NOMINAL_A1_RESTART_STAGE;
    let chose = stages
        .iter()
        .find(|st| st["name"] == restart)
        .unwrap_or_else(|| panic!("{stages:?}"));
    // ... and says which answer it passed over: the objective scored it no
    // better, and the kept answer's errors are at least the two's distance
    let other = &chose["passed_over"];
    let (kept_score, other_score) = (chose["score"].as_f64(), other["score"].as_f64());
    assert!(kept_score.unwrap() <= other_score.unwrap(), "{chose}");
    let key = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    for k in ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"] {
        let d = (key(&chose["parameters"], k) - key(&other["parameters"], k)).abs();
        let half = key(&record["interval_95"], k);
        assert!(
            half >= std::f64::consts::SQRT_2 * d - 1e-12,
            "{k}: ±{half} for {d}"
        );
    }
    // its second texture and scene fits are in the file, named as its,
    // before the choice; one of the two answers is the last of them
    let prefix = cassi_core::calib::NOMINAL_A1_RESTART_PREFIX;
    let at = stages.iter().position(|st| st["name"] == restart).unwrap();
    let again: Vec<_> = stages[..at]
        .iter()
        .filter(|st| st["name"].as_str().is_some_and(|n| n.starts_with(prefix)))
        .collect();
    assert!(again.len() >= 2, "{stages:?}");
    let last = &again[again.len() - 1]["parameters"];
    assert!(
        *last == chose["parameters"] || *last == other["parameters"],
        "{last} vs {chose}"
    );
    // only the choosing stage reports a passed-over answer
    assert!(
        stages
            .iter()
            .filter(|st| st["name"] != restart)
            .all(|st| st.get("passed_over").is_none())
    );
    std::fs::remove_file(&cal).unwrap();
    for (extra, needles) in [
        (
            &["--dispersion-a2", "0.9"][..],
            &["--dispersion-a2", "a2", "0.5"][..],
        ),
        (
            &["--preset", "paper", "--dispersion-a2", "0.001"][..],
            &["--dispersion-a2", "paper preset"][..],
        ),
        (
            &["--preset", "paper", "--blur-pass"][..],
            &["--blur-pass", "paper preset"][..],
        ),
        (
            &["--preset", "paper", "--search-rows", "32"][..],
            &["--search-rows", "paper preset"][..],
        ),
        (
            &["--preset", "paper", "--fit-curvature"][..],
            &["--fit-curvature", "paper preset"][..],
        ),
    ] {
        let args = calibrate(extra);
        assert_fails(
            &args.iter().map(String::as_str).collect::<Vec<_>>(),
            needles,
            &cal,
        );
    }
}

/// `--band-offsets FILE`: the table's shape is held, written into the
/// calibration and used by `cassi reconstruct --calibration`; tables of
/// the wrong length, in another unit or with the paper preset are refused
/// naming the file or flag, nothing written.
#[test]
fn a_band_table_travels_from_the_calibration_to_the_model() {
    let d = dir("band_table");
    let (meas, mask) = simulated(&d);
    let table = d.join("positions.txt");
    // band 2 lands 0.4 px late: positions 0, 2, 4.4, 6
    std::fs::write(&table, "# px along the dispersion\n0\n2\n4.4\n6\n").unwrap();
    let record = calibrated(&d, &meas, &mask, &["--band-offsets", s(&table)], "cal.json");
    let held = &record["band_offsets"];
    let offsets: Vec<f64> = held["offsets"]
        .as_array()
        .unwrap_or_else(|| panic!("{record}"))
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(offsets.len(), 4);
    assert_eq!(offsets[0], 0.0);
    // what is left of the table off its line through band 0: band 2 late
    assert!(
        offsets[2] > 0.2 && offsets[1] < 0.0 && offsets[3] < 0.0,
        "{offsets:?}"
    );
    let report = reconstruction_report(&meas, &mask, &d.join("cal.json"), &d.join("r.npy"));
    assert_eq!(report["band_offsets"], *held, "{report}");
    // without a table, neither the calibration nor the reconstruction has one
    let plain = calibrated(&d, &meas, &mask, &[], "plain.json");
    assert!(plain.get("band_offsets").is_none());

    let cal = d.join("refused.json");
    let five = d.join("five.csv");
    std::fs::write(&five, "0, 2, 4, 6, 8\n").unwrap();
    let nm = d.join("nm.txt");
    std::fs::write(&nm, "450 460 470 480\n").unwrap();
    for (extra, needles) in [
        (
            vec!["--band-offsets", s(&five)],
            vec!["five.csv", "5 values, expected 4"],
        ),
        (
            vec!["--band-offsets", s(&nm)],
            vec!["nm.txt", "wavelengths"],
        ),
        (
            vec!["--preset", "paper", "--band-offsets", s(&table)],
            vec!["--band-offsets", "paper preset"],
        ),
    ] {
        let mut args = vec![
            "calibrate",
            s(&meas),
            "--mask",
            s(&mask),
            "-o",
            s(&cal),
            "-q",
        ];
        args.extend(extra);
        assert_fails(&args, &needles, &cal);
    }
}

/// `--band-spread`: written into the calibration, named in the
/// reconstruction's report (the model it used), left out when a point;
/// without it, what the measurement's simulation sidecar records, else
/// uniform with the default preset's dispersed-mask model and a point with
/// the paper preset or the rounded model; refused by name with the paper
/// preset or an unknown spread, nothing written.
#[test]
fn a_band_spread_travels_from_the_calibration_to_the_model() {
    let d = dir("band_spread");
    let (meas, mask) = simulated(&d);
    // the sidecar: the rounded operator made it, a point per band
    let record = calibrated(&d, &meas, &mask, &[], "sidecar.json");
    assert!(record.get("band_spread").is_none(), "{record}");
    // the same measurement without its sidecar, as a camera's
    let bare = d.join("camera.npy");
    std::fs::copy(&meas, &bare).unwrap();
    let record = calibrated(&d, &bare, &mask, &["--bands", "4"], "default.json");
    assert_eq!(record["band_spread"], "uniform", "{record}");
    for (extra, name) in [
        (["--bands", "4", "--preset", "paper"], "paper.json"),
        (["--bands", "4", "--model", "rounded"], "rounded.json"),
    ] {
        let record = calibrated(&d, &bare, &mask, &extra, name);
        assert!(record.get("band_spread").is_none(), "{extra:?}: {record}");
    }
    // a physical simulation's sidecar records its spread, which is fitted
    let physical = simulated_as(
        &d,
        "physical.npy",
        &["--oversample", "2", "--band-spread", "linear"],
    );
    let record = calibrated(&d, &physical, &mask, &[], "physical_cal.json");
    assert_eq!(record["band_spread"], "linear", "{record}");
    let record = calibrated(&d, &meas, &mask, &["--band-spread", "linear"], "cal.json");
    assert_eq!(record["band_spread"], "linear", "{record}");
    let report = reconstruction_report(&meas, &mask, &d.join("cal.json"), &d.join("r.npy"));
    assert_eq!(report["band_spread"], "linear", "{report}");
    let plain = calibrated(&d, &meas, &mask, &["--band-spread", "point"], "plain.json");
    assert!(plain.get("band_spread").is_none(), "{plain}");
    let report = reconstruction_report(&meas, &mask, &d.join("plain.json"), &d.join("p.npy"));
    assert!(report.get("band_spread").is_none(), "{report}");
    let cal = d.join("refused.json");
    let args = |spread: &'static str, paper: bool| {
        let mut a = vec![
            "calibrate",
            s(&meas),
            "--mask",
            s(&mask),
            "-o",
            s(&cal),
            "-q",
        ];
        if paper {
            a.extend(["--preset", "paper"]);
        }
        a.extend(["--band-spread", spread]);
        a
    };
    assert_fails(
        &args("uniform", true),
        &["--band-spread", "paper preset"],
        &cal,
    );
    // an unknown name: a parse error (exit code 2) naming it and the names
    let run = cassi(&args("box", false));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("'box'") && stderr.contains("uniform"),
        "{stderr}"
    );
    assert!(!cal.exists());
}

/// `cassi calibrate MEAS --mask MASK -o D/NAME -q EXTRA…`, which must
/// succeed; the record it wrote.
fn calibrated(d: &Path, meas: &Path, mask: &Path, extra: &[&str], name: &str) -> serde_json::Value {
    let cal = d.join(name);
    let mut args = vec!["calibrate", s(meas), "--mask", s(mask), "-o", s(&cal), "-q"];
    args.extend(extra);
    ok(&cassi(&args));
    serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap()
}

#[test]
fn the_blur_pass_is_the_default_last_stage_and_no_blur_pass_leaves_it_out() {
    let d = dir("blur_pass");
    let (meas, mask) = simulated(&d);
    let run = |extra: &[&str], name: &str| calibrated(&d, &meas, &mask, extra, name);
    let record = run(&[], "cal.json");
    let stages = record["stages"].as_array().expect("stages");
    let last = stages.last().expect("a stage");
    assert_eq!(
        last["name"],
        cassi_core::calib::BLUR_PASS_STAGE,
        "{stages:?}"
    );
    // it moves σ alone: the geometry is the stage before's
    let before = &stages[stages.len() - 2];
    for k in ["dx", "dy", "theta_deg", "a1", "alpha_deg"] {
        assert_eq!(before["parameters"][k], last["parameters"][k], "{k}");
    }
    assert_eq!(record["parameters"], last["parameters"]);
    // without it the calibration ends one stage earlier, at that answer
    let without = run(&["--no-blur-pass"], "without.json");
    let without_stages = without["stages"].as_array().expect("stages");
    assert_eq!(without_stages.len(), stages.len() - 1);
    assert_eq!(without_stages.last().unwrap()["name"], before["name"]);
    assert_eq!(without["parameters"], before["parameters"]);
    // the old flag still runs (the pass was opt-in before stop 41)
    let asked = run(&["--blur-pass"], "asked.json");
    assert_eq!(asked["parameters"], record["parameters"]);
}

/// `--search-rows N` runs the search stages on N middle rows (their scores
/// are the band's), `all` on every row (the default on a frame no taller
/// than 256 rows): the same estimates' basin either way on this frame.
#[test]
fn search_rows_puts_the_search_stages_on_a_band() {
    let d = dir("search_rows");
    let (meas, mask) = simulated(&d);
    let run = |extra: &[&str], name: &str| {
        let extra: Vec<&str> = ["--no-blur-pass"].iter().chain(extra).copied().collect();
        calibrated(&d, &meas, &mask, &extra, name)
    };
    let every = run(&["--search-rows", "all"], "all.json");
    let default = run(&[], "default.json");
    assert_eq!(every["parameters"], default["parameters"]);
    let band = run(&["--search-rows", "16"], "band.json");
    // stage 1 ("refine dx, dy, θ") scores on the band: another score
    let score = |r: &serde_json::Value| r["stages"][1]["score"].as_f64().unwrap();
    assert_eq!(band["stages"][1]["name"], every["stages"][1]["name"]);
    assert!(
        (score(&band) / score(&every) - 1.0).abs() > 1e-3,
        "{} vs {}",
        score(&band),
        score(&every)
    );
    for k in ["dx", "dy"] {
        let (a, b) = (
            band["parameters"][k].as_f64().unwrap(),
            every["parameters"][k].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 0.1, "{k}: {a} vs {b}");
    }
    // no rows at all is refused by name, before any work
    let out = d.join("none.json");
    let refused = cassi(&[
        "calibrate",
        s(&meas),
        "--mask",
        s(&mask),
        "-o",
        s(&out),
        "--search-rows",
        "0",
    ]);
    assert!(!refused.status.success());
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains("--search-rows") && stderr.contains("'0'"),
        "{stderr}"
    );
    assert!(!out.exists());
}
