//! Output safety (issue #12, items 1, 2 and 7): no output may be an input
//! (same path, hard link, symbolic link, derived .json/.png names), a failed
//! or interrupted run leaves the previous outputs byte-identical, replacing
//! keeps permissions, and temporaries never outlive a run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use cassi_core::synth::random_binary_mask;
use common::{cassi, ok, s};

mod common;

/// A fresh, empty folder for one test.
fn scratch(name: &str) -> PathBuf {
    common::scratch("output-safety", name)
}

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_cassi"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the cassi binary starts")
}

/// Every file under `dir` (recursively) with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        let meta = std::fs::symlink_metadata(&path).unwrap();
        if meta.is_dir() {
            files.extend(snapshot(&path));
        } else if meta.is_file() {
            files.insert(path.clone(), std::fs::read(&path).unwrap());
        }
    }
    files
}

/// Hidden files (temporaries) under `dir`, recursively.
fn hidden(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if entry.file_name().to_string_lossy().starts_with('.') {
            found.push(path.clone());
        }
        if path.is_dir() {
            found.extend(hidden(&path));
        }
    }
    found
}

/// A size×size binary mask `mask.npy` and a synthetic measurement `m.npy`
/// of `bands` bands simulated through it (with its sidecar `m.json`), in `dir`.
fn measurement(dir: &Path, size: usize, bands: usize) -> (PathBuf, PathBuf) {
    let mask = dir.join("mask.npy");
    cassi_io::save_frame(
        &mask,
        &random_binary_mask(size, size, 0.5, 1).unwrap(),
        "mask",
    )
    .unwrap();
    let m = dir.join("m.npy");
    ok(&cassi(&[
        "simulate",
        "--synthetic",
        "--size",
        &size.to_string(),
        "--bands",
        &bands.to_string(),
        "--mask",
        s(&mask),
        "--paper-mismatch",
        "-o",
        s(&m),
        "-q",
    ]));
    assert!(dir.join("m.json").is_file());
    (m, mask)
}

/// Runs a command that must be refused before any work: exit code 1, the
/// error names every `needle`, no stage ran, and `dir` is unchanged.
fn assert_refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let before = snapshot(dir);
    let out = cassi(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "args {args:?}\nstderr: {stderr}"
    );
    assert!(stderr.contains("nothing was written"), "{stderr}");
    for n in needles {
        assert!(stderr.contains(n), "expected '{n}' in: {stderr}");
    }
    // the reporter prints a line after each finished stage: none ran
    for stage in ["simulating", "calibrating", "reconstructing", "loading"] {
        assert!(
            !stderr.contains(stage),
            "work ran before the refusal: {stderr}"
        );
    }
    assert!(snapshot(dir) == before, "args {args:?} changed the files");
    assert!(hidden(dir).is_empty(), "{:?}", hidden(dir));
}

#[test]
fn an_output_that_is_an_input_is_refused_before_any_work() {
    let dir = scratch("collisions");
    let (m, mask) = measurement(&dir, 32, 4);
    let (m, mask) = (s(&m), s(&mask));
    let j = |name: &str| dir.join(name).to_str().unwrap().to_string();
    // a hard link and a symbolic link of the inputs
    std::fs::hard_link(m, j("hard.npy")).unwrap();
    std::os::unix::fs::symlink("mask.npy", j("soft.npy")).unwrap();
    std::os::unix::fs::symlink(&dir, j("dirlink")).unwrap();
    std::fs::create_dir(j("sub")).unwrap();
    // a calibration file and a scene file to read
    ok(&cassi(&[
        "calibrate",
        m,
        "--mask",
        mask,
        "-o",
        &j("cal.json"),
        "-q",
    ]));
    let scene = j("scene.npy");
    let cube = cassi_core::synth::synthetic_scene(&cassi_core::synth::SceneSpec {
        rows: 32,
        cols: 32,
        wavelengths_nm: cassi_core::Instrument::with_bands(4, 2.0)
            .unwrap()
            .wavelengths_nm,
        seed: 0,
    })
    .unwrap();
    cassi_io::save_cube(&scene, &cube, "scene").unwrap();

    let rec = |o: &str| ["reconstruct", m, "--mask", mask, "-o", o].join("\u{0}");
    let cases: Vec<(String, Vec<&str>)> = vec![
        // reconstruct: the measurement, the mask, links to them
        (rec(m), vec!["(-o)", "(the measurement)"]),
        (rec(mask), vec!["(-o)", "(--mask)"]),
        (
            rec(&j("hard.npy")),
            vec!["hard.npy (-o)", "(the measurement)", "hard links"],
        ),
        (
            rec(&j("soft.npy")),
            vec!["soft.npy (-o)", "(--mask)", "links are followed"],
        ),
        (rec(&j("dirlink/m.npy")), vec!["(-o)", "(the measurement)"]),
        (rec(&j("sub/../m.npy")), vec!["(-o)", "(the measurement)"]),
        // the derived report name over the simulation sidecar
        (
            rec(&j("m.npz")),
            vec!["m.json (the report (-o with .json))", "sidecar"],
        ),
        // the derived report name over the calibration this run reads
        (
            [
                "reconstruct",
                m,
                "--mask",
                mask,
                "--calibration",
                &j("cal.json"),
                "-o",
                &j("cal.npy"),
            ]
            .join("\u{0}"),
            vec!["(the report (-o with .json))", "(--calibration)"],
        ),
        // the derived preview name over the truth
        (
            [
                "reconstruct",
                m,
                "--mask",
                mask,
                "--truth",
                &j("t.png"),
                "-o",
                &j("t.mat"),
            ]
            .join("\u{0}"),
            vec!["(the preview (-o with .png))", "(--truth)"],
        ),
        // calibrate: -o over the sidecar, --write-mask over the mask
        (
            ["calibrate", m, "--mask", mask, "-o", &j("m.json")].join("\u{0}"),
            vec!["m.json (-o)", "sidecar"],
        ),
        (
            [
                "calibrate",
                m,
                "--mask",
                mask,
                "-o",
                &j("c2.json"),
                "--write-mask",
                &j("soft.npy"),
            ]
            .join("\u{0}"),
            vec!["(--write-mask)", "(--mask)"],
        ),
        // simulate: over the scene, over the mask, the sidecar over a scene .json
        (
            ["simulate", "--scene", &scene, "--random-mask", "-o", &scene].join("\u{0}"),
            vec!["(-o)", "(--scene)"],
        ),
        (
            [
                "simulate",
                "--synthetic",
                "--size",
                "32",
                "--bands",
                "4",
                "--mask",
                mask,
                "-o",
                &j("soft.npy"),
                "--preview",
            ]
            .join("\u{0}"),
            vec!["soft.npy (-o)", "(--mask)"],
        ),
    ];
    for (joined, needles) in &cases {
        let args: Vec<&str> = joined.split('\u{0}').collect();
        assert_refused(&dir, &args, needles);
    }
}

#[test]
fn eval_refuses_an_output_folder_holding_its_inputs() {
    let dir = scratch("eval-collisions");
    let (_, mask) = measurement(&dir, 32, 4);
    let out = dir.join("study");
    std::fs::create_dir_all(out.join("figures")).unwrap();
    let inside = out.join("figures/mask.npy");
    std::fs::copy(&mask, &inside).unwrap();
    assert_refused(
        &dir,
        &[
            "eval",
            "--synthetic",
            "--size",
            "32",
            "--mask",
            s(&inside),
            "--out",
            s(&out),
        ],
        &["--out's figures/", "(--mask)"],
    );
}

#[test]
fn a_failed_preview_leaves_the_previous_set_byte_identical() {
    let dir = scratch("failed-preview");
    let (m, mask) = measurement(&dir, 32, 4);
    let out = dir.join("out");
    let cube = out.join("cube.npy");
    ok(&cassi(&[
        "reconstruct",
        s(&m),
        "--mask",
        s(&mask),
        "-o",
        s(&cube),
        "-q",
    ]));
    let before = snapshot(&out);
    assert_eq!(before.len(), 3, "{:?}", before.keys());
    // a one-band measurement: the cube is fine, its pseudo-RGB preview cannot
    // be made
    let one = dir.join("one");
    std::fs::create_dir(&one).unwrap();
    let (m1, mask1) = measurement(&one, 32, 1);
    let run = cassi(&[
        "reconstruct",
        s(&m1),
        "--mask",
        s(&mask1),
        "--iterations",
        "3",
        "-o",
        s(&cube),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no red component"), "{stderr}");
    assert!(snapshot(&out) == before, "the previous set changed");
    assert!(hidden(&dir).is_empty(), "{:?}", hidden(&dir));
}

#[test]
fn replacing_outputs_keeps_their_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("permissions");
    let (m, mask) = measurement(&dir, 32, 4);
    let cube = dir.join("cube.npy");
    let args = |iters: &'static str| {
        let mut a = vec![
            "reconstruct",
            s(&m),
            "--mask",
            s(&mask),
            "-o",
            s(&cube),
            "-q",
        ];
        a.extend(["--iterations", iters]);
        a.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |a: Vec<String>| ok(&cassi(&a.iter().map(String::as_str).collect::<Vec<_>>()));
    run(args("5"));
    let modes = [
        ("cube.npy", 0o600),
        ("cube.json", 0o640),
        ("cube.png", 0o604),
    ];
    for (name, mode) in modes {
        std::fs::set_permissions(dir.join(name), std::fs::Permissions::from_mode(mode)).unwrap();
    }
    let old = std::fs::read(&cube).unwrap();
    run(args("9"));
    assert_ne!(
        std::fs::read(&cube).unwrap(),
        old,
        "the cube was not replaced"
    );
    for (name, mode) in modes {
        let got = std::fs::metadata(dir.join(name))
            .unwrap()
            .permissions()
            .mode()
            & 0o777;
        assert_eq!(got, mode, "{name}: {got:o}");
    }
}

#[test]
fn stale_temporaries_of_killed_runs_are_removed_live_ones_kept() {
    let dir = scratch("stale");
    let (m, mask) = measurement(&dir, 32, 4);
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    // no process has a PID this large (Linux's pid_max is at most 2^22)
    let dead = out.join(".cube.npy.cassi-tmp2000000000-0");
    let legacy = out.join(".cube.png.tmp2000000001-3"); // earlier cassi versions
    let live = out.join(format!(".cube.json.cassi-tmp{}-0", std::process::id()));
    for p in [&dead, &legacy, &live] {
        std::fs::write(p, vec![0u8; 1000]).unwrap();
    }
    ok(&cassi(&[
        "reconstruct",
        s(&m),
        "--mask",
        s(&mask),
        "-o",
        s(&out.join("cube.npy")),
        "-q",
    ]));
    assert!(!dead.exists() && !legacy.exists(), "{:?}", hidden(&out));
    assert!(live.exists(), "a live process's temporary was removed");
    assert_eq!(hidden(&out), vec![live]);
}

/// Sends `signal` (e.g. "-INT") to the child.
fn kill(child: &Child, signal: &str) {
    let status = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success());
}

/// Waits for the child, at most `limit`.
fn wait(child: &mut Child, limit: Duration) -> (ExitStatus, String) {
    let t0 = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut stderr = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut stderr)
                .unwrap();
            return (status, stderr);
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            panic!("the process did not end within {limit:?} of the signal");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_signal_during_reconstruction_leaves_the_previous_outputs() {
    let dir = scratch("signal-reconstruct");
    let (m, mask) = measurement(&dir, 32, 4);
    let cube = dir.join("out/cube.npy");
    ok(&cassi(&[
        "reconstruct",
        s(&m),
        "--mask",
        s(&mask),
        "-o",
        s(&cube),
        "-q",
    ]));
    let before = snapshot(&dir);
    for signal in ["-INT", "-TERM"] {
        // far more iterations than the test waits for (the parser caps --iterations at 100000)
        let mut child = spawn(&[
            "reconstruct",
            s(&m),
            "--mask",
            s(&mask),
            "-o",
            s(&cube),
            "--iterations",
            "100000",
        ]);
        std::thread::sleep(Duration::from_millis(700));
        assert!(
            child.try_wait().unwrap().is_none(),
            "it ended before the signal"
        );
        kill(&child, signal);
        let (status, stderr) = wait(&mut child, Duration::from_secs(20));
        assert_eq!(status.code(), Some(130), "{signal}: {stderr}");
        assert!(stderr.contains("interrupted"), "{stderr}");
        assert!(
            snapshot(&dir) == before,
            "{signal}: the previous outputs changed"
        );
        assert!(hidden(&dir).is_empty(), "{:?}", hidden(&dir));
    }
}

#[test]
fn a_signal_during_calibration_leaves_the_previous_outputs() {
    let dir = scratch("signal-calibrate");
    let (m, mask) = measurement(&dir, 64, 8);
    let cal = dir.join("cal.json");
    let warped = dir.join("warped.npy");
    let args = |preset: &'static str| {
        vec![
            "calibrate",
            s(&m),
            "--mask",
            s(&mask),
            "-o",
            s(&cal),
            "--write-mask",
            s(&warped),
            "--preset",
            preset,
        ]
    };
    ok(&cassi(&args("default")));
    let before = snapshot(&dir);
    // the paper preset takes seconds here; one signal, then two in a row
    for signals in [&["-INT"][..], &["-TERM", "-INT"][..]] {
        let mut child = spawn(&args("paper"));
        std::thread::sleep(Duration::from_millis(700));
        assert!(
            child.try_wait().unwrap().is_none(),
            "it ended before the signal"
        );
        for signal in signals {
            kill(&child, signal);
            std::thread::sleep(Duration::from_millis(50));
        }
        let (status, stderr) = wait(&mut child, Duration::from_secs(20));
        assert_eq!(status.code(), Some(130), "{signals:?}: {stderr}");
        assert!(stderr.contains("interrupted"), "{stderr}");
        assert!(
            snapshot(&dir) == before,
            "{signals:?}: the previous outputs changed"
        );
        assert!(hidden(&dir).is_empty(), "{:?}", hidden(&dir));
    }
}

#[test]
fn calibrate_checks_its_output_name_before_the_run() {
    let dir = scratch("calibrate-name");
    let (m, mask) = measurement(&dir, 32, 4);
    let t0 = Instant::now();
    let out = cassi(&[
        "calibrate",
        s(&m),
        "--mask",
        s(&mask),
        "-o",
        s(&dir.join("cal.txt")),
        "--preset",
        "paper",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("use a .json name"), "{stderr}");
    assert!(
        !stderr.contains("calibrating"),
        "the calibration ran first: {stderr}"
    );
    assert!(t0.elapsed() < Duration::from_secs(10));
}
