//! `cassi simulate --oversample`: the physical instrument from the command
//! line — shape, sidecar, the library's numbers, and clear refusals.

use std::path::PathBuf;

use cassi_core::optics::{BandSpread, Halo, NoiseModel, PhysicalSpec, simulate_physical};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Instrument, Mismatch};
use common::{assert_fails, cassi, ok, s};

mod common;

fn scratch(name: &str) -> PathBuf {
    common::scratch("physical-tests", name)
}

const BASE: [&str; 10] = [
    "simulate",
    "--synthetic",
    "--size",
    "32",
    "--bands",
    "4",
    "--random-mask",
    "--mask-seed",
    "2",
    "--quiet",
];

fn args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    BASE.iter().copied().chain(extra.iter().copied()).collect()
}

#[test]
fn oversampled_simulation_has_the_fixed_detector_and_a_full_sidecar() {
    let dir = scratch("physical");
    let meas = dir.join("phys.npy");
    let mismatch = [
        "--dx", "0.4", "--dy", "-0.3", "--theta", "0.2", "--a1", "2.05",
    ];
    let physical = [
        "--oversample",
        "4",
        "--blur",
        "0.5",
        "--blur-slope",
        "0.001",
        "--detector",
        "32x40",
        "--adc-bits",
        "12",
        "--photon-peak",
        "20000",
        "--read-noise",
        "3",
        "--noise-seed",
        "5",
    ];
    let mut a = args(&mismatch);
    a.extend(physical);
    a.extend(["-o", s(&meas)]);
    ok(&cassi(&a));
    let y = cassi_io::load_frame(&meas, None).unwrap();
    assert_eq!(y.shape(), (32, 40));

    // the sidecar records the physical instrument, the mismatch and the noise
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("phys.json")).unwrap()).unwrap();
    let spec: PhysicalSpec = serde_json::from_value(sidecar["physical"].clone()).unwrap();
    assert_eq!(
        spec,
        PhysicalSpec {
            oversample: 4,
            blur_sigma_px: 0.5,
            blur_slope_px_per_nm: 0.001,
            detector: Some((32, 40)),
            adc_bits: Some(12),
            halo: None,
            dispersion_a2: 0.0,
            dispersion_step: None,
            band_spread: BandSpread::Point,
        }
    );
    assert_eq!(sidecar["measurement"]["shape"], serde_json::json!([32, 40]));
    assert_eq!(sidecar["simulation"]["mismatch"]["dx"], 0.4);
    // the true parameters carry the blur σ₀, so the sidecar is the oracle model
    assert_eq!(sidecar["simulation"]["mismatch"]["blur_sigma_px"], 0.5);
    assert_eq!(sidecar["simulation"]["noise"]["read_noise"], 3.0);
    assert_eq!(sidecar["simulation"]["model"], "subpixel");

    // exactly the library's numbers
    let instrument = Instrument::with_bands(4, 2.0).unwrap();
    let scene = synthetic_scene(&SceneSpec {
        rows: 32,
        cols: 32,
        wavelengths_nm: instrument.wavelengths_nm.clone(),
        seed: 0,
    })
    .unwrap();
    let mask = random_binary_mask(32, 32, 0.5, 2).unwrap();
    let m = Mismatch {
        dx: 0.4,
        dy: -0.3,
        theta_deg: 0.2,
        a1: 2.05,
        alpha_deg: 0.0,
        ..Mismatch::nominal(2.0)
    };
    let noise = NoiseModel {
        photon_peak: Some(20000.0),
        read_noise: 3.0,
        seed: 5,
    };
    let want = simulate_physical(
        &scene,
        &mask,
        &instrument.wavelengths_nm,
        &m,
        &spec,
        Some(&noise),
    )
    .unwrap();
    assert_eq!(y, want);

    // the sidecar as a model: reconstruct uses the blurred operator, which
    // explains the measurement better than the same parameters without blur
    let residual = |calibration: &PathBuf, name: &str| {
        let out = dir.join(name);
        ok(&cassi(&[
            "reconstruct",
            s(&meas),
            "--mask",
            s(&dir.join("mask.npy")),
            "--calibration",
            s(calibration),
            "--iterations",
            "30",
            "-o",
            s(&out),
        ]));
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.with_extension("json")).unwrap()).unwrap();
        report["relative_residual"].as_f64().unwrap()
    };
    cassi_io::save_frame(
        dir.join("mask.npy"),
        &random_binary_mask(32, 32, 0.5, 2).unwrap(),
        "mask",
    )
    .unwrap();
    let blurred = residual(&dir.join("phys.json"), "oracle.npy");
    let mut sharp_sidecar = sidecar.clone();
    sharp_sidecar["simulation"]["mismatch"]["blur_sigma_px"] = serde_json::json!(0.0);
    let sharp_path = dir.join("sharp_model.json");
    std::fs::write(&sharp_path, serde_json::to_vec(&sharp_sidecar).unwrap()).unwrap();
    let sharp = residual(&sharp_path, "sharp.npy");
    assert!(
        blurred < sharp,
        "blurred model residual {blurred} vs sharp {sharp}"
    );

    // not the discrete measurement of the same instrument
    let discrete = dir.join("discrete.npy");
    let mut a = args(&mismatch);
    a.extend([
        "--model",
        "subpixel",
        "--photon-peak",
        "20000",
        "--read-noise",
        "3",
        "--noise-seed",
        "5",
        "-o",
        s(&discrete),
    ]);
    ok(&cassi(&a));
    let d = cassi_io::load_frame(&discrete, None).unwrap();
    assert_eq!(d.shape(), (32, 39), "the discrete default detector");
    let (mut diff, mut energy) = (0.0f64, 0.0f64);
    for r in 0..32 {
        for c in 0..39 {
            diff += ((y.get(r, c) - d.get(r, c)) as f64).powi(2);
            energy += (d.get(r, c) as f64).powi(2);
        }
    }
    let rel = (diff / energy).sqrt();
    assert!(
        rel > 0.02,
        "physical vs discrete: relative difference {rel}"
    );
    // the sidecar of a discrete simulation has no physical record
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("discrete.json")).unwrap()).unwrap();
    assert!(sidecar.get("physical").is_none());
}

#[test]
fn physical_flags_are_checked_and_name_themselves() {
    let dir = scratch("refusals");
    let out = dir.join("x.npy");
    let o = s(&out);
    // parse errors (clap: exit code 2) name the flag
    for (extra, needle) in [
        (
            vec!["--oversample", "4", "--detector", "256x"],
            "--detector",
        ),
        (
            vec!["--oversample", "4", "--detector", "256x"],
            "expected ROWSxCOLS",
        ),
        (vec!["--oversample", "0"], "--oversample"),
        (vec!["--oversample", "2", "--blur", "-1"], "--blur"),
        (vec!["--oversample", "2", "--adc-bits", "40"], "--adc-bits"),
        (vec!["--oversample", "2", "--halo", "1.2,2"], "--halo"),
        (vec!["--oversample", "2", "--halo", "0.2"], "SHARE,SIGMA"),
        (vec!["--halo", "0.2,2"], "--oversample"),
        (
            vec!["--oversample", "2", "--dispersion-a2", "0.6"],
            "--dispersion-a2",
        ),
        (
            vec!["--oversample", "2", "--dispersion-step", "2:3"],
            "--dispersion-step",
        ),
        (
            vec!["--oversample", "2", "--dispersion-step", "0:0.5"],
            "K:PX",
        ),
        (vec!["--oversample", "2", "--band-spread", "box"], "'box'"),
        (vec!["--band-spread", "linear"], "--oversample"),
        (vec!["--blur", "0.5"], "--oversample"),
        (vec!["--oversample", "4", "--model", "rounded"], "--model"),
    ] {
        let mut a = args(&extra);
        a.extend(["-o", o]);
        let run = cassi(&a);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(needle), "{extra:?}: {stderr}");
        assert!(!out.exists());
    }
    // checks after loading (exit code 1)
    let mut a = args(&["--oversample", "4", "--detector", "30x40", "-o", o]);
    a.retain(|x| *x != "--quiet");
    assert_fails(&a, &["--detector 30x40", "32 rows"], &out);
    let a = args(&[
        "--oversample",
        "4",
        "--blur",
        "0.2",
        "--blur-slope",
        "0.01",
        "-o",
        o,
    ]);
    assert_fails(&a, &["blur_slope", "band 0"], &out);
    // a step past the last band: refused once the band count is known
    let a = args(&["--oversample", "4", "--dispersion-step", "4:0.5", "-o", o]);
    assert_fails(&a, &["dispersion_step.from_band", "of the 4"], &out);
}

/// `--halo SHARE,SIGMA` goes into the sidecar's physical spec and into the
/// snapshot: the library's numbers with that halo, not the blur alone's.
#[test]
fn a_halo_is_simulated_and_recorded() {
    let dir = scratch("halo");
    let (with, without) = (dir.join("halo.npy"), dir.join("plain.npy"));
    let common = ["--oversample", "4", "--blur", "0.4", "--no-noise"];
    let mut a = args(&common);
    a.extend(["--halo", "0.3,2", "-o", s(&with)]);
    ok(&cassi(&a));
    let mut a = args(&common);
    a.extend(["-o", s(&without)]);
    ok(&cassi(&a));
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("halo.json")).unwrap()).unwrap();
    let spec: PhysicalSpec = serde_json::from_value(sidecar["physical"].clone()).unwrap();
    assert_eq!(
        spec.halo,
        Some(Halo {
            share: 0.3,
            sigma_px: 2.0
        })
    );
    let (y, plain) = (
        cassi_io::load_frame(&with, None).unwrap(),
        cassi_io::load_frame(&without, None).unwrap(),
    );
    assert_eq!(y.shape(), plain.shape());
    assert!(y.as_slice() != plain.as_slice());
    // light is moved, not made: the totals agree away from the frame's edge
    let (t, p): (f64, f64) = (
        y.as_slice().iter().map(|&v| v as f64).sum(),
        plain.as_slice().iter().map(|&v| v as f64).sum(),
    );
    assert!((t - p).abs() < 0.05 * p, "{t} vs {p}");

    // a curved dispersion likewise: recorded, and another snapshot
    let curved = dir.join("curved.npy");
    let mut a = args(&common);
    a.extend(["--dispersion-a2", "0.01", "-o", s(&curved)]);
    ok(&cassi(&a));
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("curved.json")).unwrap()).unwrap();
    assert_eq!(sidecar["physical"]["dispersion_a2"], 0.01);
    let y = cassi_io::load_frame(&curved, None).unwrap();
    assert!(y.as_slice() != plain.as_slice());

    // and a stepped one
    let stepped = dir.join("stepped.npy");
    let mut a = args(&common);
    a.extend(["--dispersion-step", "2:0.5", "-o", s(&stepped)]);
    ok(&cassi(&a));
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("stepped.json")).unwrap()).unwrap();
    assert_eq!(
        sidecar["physical"]["dispersion_step"],
        serde_json::json!({"from_band": 2, "px": 0.5})
    );
    let y = cassi_io::load_frame(&stepped, None).unwrap();
    assert!(y.as_slice() != plain.as_slice());

    // and each band's light spread between its neighbours; the default
    // (point) is not written, so older sidecars read and write as before
    let spread = dir.join("spread.npy");
    let mut a = args(&common);
    a.extend(["--band-spread", "uniform", "-o", s(&spread)]);
    ok(&cassi(&a));
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("spread.json")).unwrap()).unwrap();
    assert_eq!(sidecar["physical"]["band_spread"], "uniform");
    let plain_sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("plain.json")).unwrap()).unwrap();
    assert!(plain_sidecar["physical"].get("band_spread").is_none());
    let y = cassi_io::load_frame(&spread, None).unwrap();
    assert!(y.as_slice() != plain.as_slice());
}
