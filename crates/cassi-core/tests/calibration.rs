//! Self-calibration on small synthetic problems: the score is minimal at the
//! truth, and the `default` preset recovers known parameters.

use cassi_core::Mismatch;
use cassi_core::calib::{CalibrationProblem, DefaultPreset, ProxyParams, calibrate_default};
use cassi_core::optics::{DispersionModel, SimulationSpec, simulate};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};

fn setup(
    size: usize,
    bands: usize,
    truth: Mismatch,
    model: DispersionModel,
) -> (cassi_core::Measurement, cassi_core::Mask) {
    let wl: Vec<f64> = (0..bands)
        .map(|k| 450.0 + 200.0 * k as f64 / (bands - 1) as f64)
        .collect();
    let scene = synthetic_scene(&SceneSpec {
        rows: size,
        cols: size,
        wavelengths_nm: wl,
        seed: 5,
    })
    .unwrap();
    let mask = random_binary_mask(size, size, 0.5, 2).unwrap();
    let y = simulate(
        &scene,
        &mask,
        &SimulationSpec {
            mismatch: truth,
            model,
            noise: None,
        },
    )
    .unwrap();
    (y, mask)
}

#[test]
fn the_score_is_minimal_at_the_truth_without_noise() {
    let truth = Mismatch {
        dx: 1.2,
        dy: -0.7,
        theta_deg: 0.4,
        a1: 2.0,
        alpha_deg: 0.0,
    };
    let (y, mask) = setup(64, 8, truth, DispersionModel::Rounded);
    let p = CalibrationProblem {
        measurement: &y,
        nominal_mask: &mask,
        bands: 8,
        model: DispersionModel::Rounded,
    };
    let proxy = ProxyParams::default();
    let at = p.score(&truth, &proxy).unwrap();
    let off = [
        Mismatch {
            dx: truth.dx + 0.25,
            ..truth
        },
        Mismatch {
            dx: truth.dx - 0.25,
            ..truth
        },
        Mismatch {
            dy: truth.dy + 0.25,
            ..truth
        },
        Mismatch {
            dy: truth.dy - 0.25,
            ..truth
        },
        Mismatch {
            theta_deg: truth.theta_deg + 0.3,
            ..truth
        },
        Mismatch { a1: 2.2, ..truth },
        Mismatch::nominal(2.0),
    ];
    for m in off {
        let s = p.score(&m, &proxy).unwrap();
        assert!(
            s > 1.2 * at,
            "score {s} at {m:?} not above {at} at the truth"
        );
    }
}

#[test]
fn default_preset_recovers_a_known_mask_misalignment() {
    for model in [DispersionModel::Rounded, DispersionModel::Subpixel] {
        let truth = Mismatch {
            dx: 1.3,
            dy: -0.8,
            theta_deg: 0.35,
            a1: 2.0,
            alpha_deg: 0.0,
        };
        let (y, mask) = setup(96, 8, truth, model);
        let p = CalibrationProblem {
            measurement: &y,
            nominal_mask: &mask,
            bands: 8,
            model,
        };
        let cal = calibrate_default(&p, &DefaultPreset::default(), &mut |_| {}).unwrap();
        let e = cal.parameters;
        assert!((e.dx - truth.dx).abs() < 0.1, "{model:?}: {e:?}");
        assert!((e.dy - truth.dy).abs() < 0.1, "{model:?}: {e:?}");
        assert!(
            (e.theta_deg - truth.theta_deg).abs() < 0.15,
            "{model:?}: {e:?}"
        );
        assert!((e.a1 - truth.a1).abs() < 0.03, "{model:?}: {e:?}");
        assert!(cal.score < cal.nominal_score / 2.0);
        assert_eq!(cal.stages.len(), 4);
    }
}
