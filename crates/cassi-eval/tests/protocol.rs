//! The four-scenario protocol on a small synthetic case: the scenarios order
//! as they must, calibration recovers most of the oracle gap, and the
//! summary's arithmetic (means, ρ, RMSE) is right.

use cassi_core::calib::Preset;
use cassi_core::optics::{DispersionModel, NoiseModel};
use cassi_core::recon::Method;
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Cube, Mask, Mismatch, Parameter};
use cassi_eval::protocol::{Scenario, SceneProgress, Study, run_scene};
use cassi_eval::summary::summarize;

fn case(size: usize, bands: usize) -> (Cube, Mask) {
    let scene = synthetic_scene(&SceneSpec {
        rows: size,
        cols: size,
        wavelengths_nm: (0..bands).map(|k| 450.0 + 25.0 * k as f64).collect(),
        seed: 2,
    })
    .unwrap();
    (scene, random_binary_mask(size, size, 0.5, 4).unwrap())
}

#[test]
fn scenarios_order_as_they_must_and_calibration_closes_the_gap() {
    let (scene, mask) = case(80, 8);
    let study = Study {
        mismatch: Mismatch {
            dx: 1.3,
            dy: -0.8,
            theta_deg: 0.35,
            a1: 2.0,
            alpha_deg: 0.0,
            ..Mismatch::nominal(2.0)
        },
        instrument: DispersionModel::Rounded,
        noise: NoiseModel::default(),
        preset: Preset::by_name("default", 2.0).unwrap(),
        methods: vec![
            Method::by_name("gap-tv")
                .unwrap()
                .with_overrides(Some(40), None)
                .into(),
        ],
        stride: 2.0,
    };
    let mut steps = Vec::new();
    let mut stages = Vec::new();
    let (r, kept) = run_scene(
        "synthetic",
        &scene,
        &mask,
        &study,
        7,
        true,
        &mut |p| match p {
            SceneProgress::Step(s) => steps.push(s.to_string()),
            SceneProgress::CalibrationStage(s) => stages.push(s.to_string()),
        },
    )
    .unwrap();
    assert_eq!(kept.len(), 5);
    assert!(kept.iter().all(|(_, c)| c.shape() == scene.shape()));
    assert_eq!(r.outcomes.len(), 5);
    assert!(
        steps.iter().any(|s| s.contains("III Corrected")),
        "{steps:?}"
    );
    // counted steps as the progress bar expects, and every calibration
    // stage heard (a front end's stop points inside the calibration)
    assert_eq!(steps.len() as u64, study.steps_per_scene(), "{steps:?}");
    let recorded: Vec<&str> = r
        .calibration
        .stages
        .iter()
        .map(|s| s.name.as_str())
        .collect();
    assert!(!stages.is_empty());
    assert_eq!(stages, recorded);
    let p = |s| r.outcome("gap-tv", s).unwrap().metrics.psnr;
    let (ideal, assumed, corrected, oracle) = (
        p(Scenario::IdealClean),
        p(Scenario::Assumed),
        p(Scenario::Corrected),
        p(Scenario::Oracle),
    );
    assert!(
        oracle > assumed + 2.0,
        "oracle {oracle} vs assumed {assumed}"
    );
    assert!(
        corrected > oracle - 0.3,
        "corrected {corrected} vs oracle {oracle}"
    );
    assert!(ideal > assumed, "ideal {ideal} vs assumed {assumed}");
    assert!(
        r.errors.get(Parameter::Dx).abs() < 0.1 && r.errors.get(Parameter::Dy).abs() < 0.1,
        "{:?}",
        r.errors
    );

    // the summary of two copies: same means, ρ from the gains, RMSE = |error|
    let mut other = r.clone();
    other.scene = "copy".into();
    let s = summarize(&[r.clone(), other]);
    let m = &s.methods[0];
    assert_eq!(m.scenario(Scenario::Oracle).unwrap().psnr, oracle);
    let rho = (corrected - assumed) / (oracle - assumed);
    assert!((m.recovery_ratio - rho).abs() < 1e-12);
    assert_eq!(m.recovery_ratio_per_scene.len(), 2);
    assert!(
        (s.parameter_rmse.get(Parameter::Dx) - r.errors.get(Parameter::Dx).abs()).abs() < 1e-12
    );
}
