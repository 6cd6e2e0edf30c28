//! The `paper` preset (Algorithm 1) end to end on a small synthetic case:
//! grids, three Adam stages through the unrolled proxy, selection, a1.

use cassi_core::Mismatch;
use cassi_core::calib::{CalibrationProblem, PaperPreset, calibrate_paper};
use cassi_core::optics::{DispersionModel, SimulationSpec, simulate};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};

#[test]
fn paper_preset_recovers_a_known_mask_misalignment() {
    let (size, bands) = (64, 8);
    let scene = synthetic_scene(&SceneSpec {
        rows: size,
        cols: size,
        wavelengths_nm: (0..bands).map(|k| 450.0 + 25.0 * k as f64).collect(),
        seed: 5,
    })
    .unwrap();
    let mask = random_binary_mask(size, size, 0.5, 2).unwrap();
    // off the 0.75 px / ⅓° grid, so the gradient stages must do the last part
    let truth = Mismatch {
        dx: 1.2,
        dy: -0.55,
        theta_deg: 0.45,
        a1: 2.0,
        alpha_deg: 0.0,
        ..Mismatch::nominal(2.0)
    };
    let model = DispersionModel::Rounded;
    let spec = SimulationSpec {
        mismatch: truth,
        model,
        noise: None,
    };
    let y = simulate(&scene, &mask, &spec).unwrap();
    let problem = CalibrationProblem::nominal(&y, &mask, bands, 2.0, model).unwrap();
    let mut names = Vec::new();
    let cal = calibrate_paper(&problem, &PaperPreset::default(), &mut |s| {
        names.push(s.name.clone())
    })
    .unwrap();
    let e = cal.parameters;
    assert!((e.dx - truth.dx).abs() < 0.05, "{e:?}");
    assert!((e.dy - truth.dy).abs() < 0.05, "{e:?}");
    assert!((e.theta_deg - truth.theta_deg).abs() < 0.05, "{e:?}");
    // with 8 bands every a1 in (2 − 0.5/7, 2 + 0.5/7) rounds to the same offsets
    assert!((e.a1 - 2.0).abs() < 0.5 / 7.0, "{e:?}");
    assert!(cal.score < cal.nominal_score / 2.0);
    // the truth is off the grid, so the result must come from the Adam stages
    assert!(
        names.iter().any(|n| n == "3 selection (gradient)"),
        "{names:?}"
    );
    assert_eq!(names.len(), 7, "{names:?}");
}
