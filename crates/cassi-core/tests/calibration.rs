//! Self-calibration on small synthetic problems: the score is minimal at the
//! truth, and the `default` preset recovers known parameters.

use cassi_core::calib::{
    BLUR_BOOTSTRAP_STAGE, BLUR_PASS_STAGE, BlurBootstrap, BlurPass, Calibration,
    CalibrationProblem, DETAIL_PASS_STAGE, DefaultPreset, Fit, NOMINAL_START_STAGE,
    ON_GRID_MARGIN_PX, ProxyParams, ReconstructionSigma, TEXTURE_START_MAX_PX, calibrate_default,
};
use cassi_core::optics::{DispersionModel, SimulationSpec, simulate};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Mismatch, Parameter};

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

/// The search band's tests: a pose turned about the centre of a 96-row
/// frame (8 bands, the rounded model) and its measurement.
fn turned_pose_on_a_tall_frame() -> (
    Mismatch,
    DispersionModel,
    cassi_core::Measurement,
    cassi_core::Mask,
) {
    let truth = Mismatch {
        dx: 1.3,
        dy: -0.8,
        theta_deg: 0.35,
        ..Mismatch::nominal(2.0)
    };
    let model = DispersionModel::Rounded;
    let (y, mask) = setup(96, 8, truth, model);
    (truth, model, y, mask)
}

/// On a frame taller than `search_rows` the search stages run on its
/// middle rows: their scores are the band's (not the frame's), and they
/// still find the basin of a pose turned about the frame's centre.
#[test]
fn the_search_stages_run_on_a_band_of_a_tall_frame() {
    let (truth, model, y, mask) = turned_pose_on_a_tall_frame();
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, model).unwrap();
    let run = |search_rows| {
        let preset = DefaultPreset {
            search_rows,
            ..DefaultPreset::default()
        };
        let cal = calibrate_default(&p, &preset, &mut |_| {}).unwrap();
        // stage 3b, the last search stage, and the frame's own search score there
        let searched = cal.stages[3].clone();
        assert_eq!(searched.name, "re-fit pose per dispersion");
        let proxy = ProxyParams {
            iterations: preset.search_iterations,
            ..preset.proxy
        };
        let frame_score = p.score(&searched.parameters, &proxy).unwrap();
        (cal, searched, frame_score)
    };
    let (whole, searched, frame_score) = run(None);
    assert_eq!(searched.score, frame_score);
    let (band, searched, frame_score) = run(Some(40));
    assert!(
        (searched.score / frame_score - 1.0).abs() > 1e-3,
        "the band's score {} is the frame's {frame_score}",
        searched.score
    );
    let s = searched.parameters;
    assert!((s.dx - truth.dx).abs() < 0.15, "{s:?}");
    assert!((s.dy - truth.dy).abs() < 0.15, "{s:?}");
    assert!((s.theta_deg - truth.theta_deg).abs() < 0.15, "{s:?}");
    for cal in [whole, band] {
        let e = cal.parameters;
        assert!((e.dx - truth.dx).abs() < 0.1, "{e:?}");
        assert!((e.dy - truth.dy).abs() < 0.1, "{e:?}");
    }
}

/// A tall frame whose middle rows are dark: the search band moves to the
/// rows that hold the scene (`RowWindow::centred_unless_blind`), and the
/// search finds the pose's basin there, where the middle band, seeing
/// nothing, cannot.
#[test]
fn the_search_band_leaves_a_dark_middle() {
    let (truth, model, y, mask) = turned_pose_on_a_tall_frame();
    let (rows, cols) = y.shape();
    // rows 24..96 dark: the scene lies in the top quarter
    let dark: Vec<f32> = y
        .as_slice()
        .iter()
        .enumerate()
        .map(|(i, &v)| if i / cols < 24 { v } else { 0.0 })
        .collect();
    let y = cassi_core::Measurement::from_vec(rows, cols, dark).unwrap();
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, model).unwrap();
    let preset = DefaultPreset {
        search_rows: Some(16),
        ..DefaultPreset::default()
    };
    let cal = calibrate_default(&p, &preset, &mut |_| {}).unwrap();
    let searched = &cal.stages[3];
    assert_eq!(searched.name, "re-fit pose per dispersion");
    let s = searched.parameters;
    assert!((s.dx - truth.dx).abs() < 0.2, "{s:?}");
    assert!((s.dy - truth.dy).abs() < 0.2, "{s:?}");
    assert!((s.theta_deg - truth.theta_deg).abs() < 0.2, "{s:?}");
}

#[test]
fn the_score_is_minimal_at_the_truth_without_noise() {
    let truth = Mismatch {
        dx: 1.2,
        dy: -0.7,
        theta_deg: 0.4,
        a1: 2.0,
        alpha_deg: 0.0,
        ..Mismatch::nominal(2.0)
    };
    let (y, mask) = setup(64, 8, truth, DispersionModel::Rounded);
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::Rounded).unwrap();
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
fn the_subpixel_score_is_minimal_at_the_true_dispersion() {
    // the subpixel proxy once diverged (GAP step normalised by diag(A Aᵀ) of
    // a non-diagonal A Aᵀ) and scored the true tilt far worse than α = 0
    let truth = Mismatch {
        dx: 1.2,
        dy: -0.7,
        theta_deg: 0.4,
        a1: 2.05,
        alpha_deg: 1.5,
        ..Mismatch::nominal(2.0)
    };
    let (y, mask) = setup(64, 8, truth, DispersionModel::Subpixel);
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::Subpixel).unwrap();
    let proxy = ProxyParams::default();
    let at = p.score(&truth, &proxy).unwrap();
    for m in [
        Mismatch {
            alpha_deg: 0.0,
            ..truth
        },
        Mismatch {
            alpha_deg: 3.0,
            ..truth
        },
        Mismatch { a1: 2.0, ..truth },
        Mismatch { a1: 2.1, ..truth },
    ] {
        let s = p.score(&m, &proxy).unwrap();
        assert!(
            s > 1.02 * at,
            "score {s} at {m:?} not above {at} at the truth"
        );
    }
}

/// A shifted, turned mask behind a drifted, tilted prism (band 7 lands 14.49
/// columns and 0.38 rows away).
fn drifted_prism() -> Mismatch {
    Mismatch {
        dx: 1.3,
        dy: -0.8,
        theta_deg: 0.35,
        a1: 2.07,
        alpha_deg: 1.5,
        ..Mismatch::nominal(2.0)
    }
}

#[test]
fn default_preset_recovers_a_known_mask_misalignment() {
    // rounded: a1 and α act only through the rounding pattern, so the truth
    // keeps the nominal one; the other models: the drifted, tilted prism,
    // which the preset must recover
    let drifted = drifted_prism();
    let cases = [
        (
            DispersionModel::Rounded,
            Mismatch {
                dx: 1.3,
                dy: -0.8,
                theta_deg: 0.35,
                a1: 2.0,
                alpha_deg: 0.0,
                ..Mismatch::nominal(2.0)
            },
        ),
        (DispersionModel::Subpixel, drifted),
        (DispersionModel::DispersedMask, drifted),
        (DispersionModel::CrispCells, drifted),
    ];
    for (model, truth) in cases {
        let (y, mask) = setup(96, 8, truth, model);
        let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, model).unwrap();
        let cal = calibrate_default(&p, &DefaultPreset::default(), &mut |_| {}).unwrap();
        let e = cal.parameters;
        eprintln!("{model:?}: {e:?}");
        assert!((e.dx - truth.dx).abs() < 0.1, "{model:?}: {e:?}");
        assert!((e.dy - truth.dy).abs() < 0.1, "{model:?}: {e:?}");
        assert!(
            (e.theta_deg - truth.theta_deg).abs() < 0.15,
            "{model:?}: {e:?}"
        );
        match model {
            DispersionModel::Rounded => assert!((e.a1 - truth.a1).abs() < 0.03, "{e:?}"),
            DispersionModel::Subpixel
            | DispersionModel::DispersedMask
            | DispersionModel::CrispCells => {
                assert!((e.a1 - truth.a1).abs() < 0.02, "{e:?}");
                assert!((e.alpha_deg - truth.alpha_deg).abs() < 0.5, "{e:?}");
            }
        }
        // a sharp instrument is reported sharp: well below a pixel, and
        // zero within the stated standard error where one is stated
        assert!(e.blur_sigma_px < 0.1, "{e:?}");
        if let Some(u) = cal.uncertainty.get(Parameter::BlurSigmaPx) {
            // the crisp-cell model's blind scene fit reads σ high on
            // textured scenes (+0.06 px on the benchmark's tuning-half
            // random poses, `bench/results/calibrate_physical_tuning_crisp_cells.json`);
            // here 0.052 ± 0.043: within two standard errors
            let allowed = if model.places_cells() { 2.0 * u } else { u };
            assert!(e.blur_sigma_px <= allowed, "blur {} ± {u}", e.blur_sigma_px);
        }
        assert!(cal.score < cal.nominal_score / 2.0);
        // the texture fit replaces the subpixel model's proxy refinements
        // (tilt, joint), and the dispersed-mask model ends in the scene fit
        // and its fine pass, each a stage, then the blur pass (σ alone);
        // the rounded model keeps its joint refinement and does not fit the
        // blur
        let last = cal.stages.last().map(|s| s.name.as_str()).unwrap_or("");
        match model {
            DispersionModel::DispersedMask | DispersionModel::CrispCells => {
                // a1 2.07 lies beyond the nominal start's gap from the
                // stride: the first pass runs again from a1 = 2, α = 0, and
                // the choosing stage keeps the lower objective
                assert_eq!(cal.stages.len(), 10);
                let first = cal.stages[5].name.as_str();
                assert!(first.starts_with("scene fit ("), "{first}");
                let chose = &cal.stages[6];
                assert_eq!(chose.name, NOMINAL_START_STAGE);
                let passed = chose.passed_over.as_ref().expect("the answer passed over");
                assert!(chose.score <= passed.score, "{chose:?}");
                assert!(cal.stages[5].passed_over.is_none());
                assert_eq!(cal.stages[7].name, DETAIL_PASS_STAGE);
                let fine = cal.stages[8].name.as_str();
                assert!(fine.starts_with("scene fit's fine pass"), "{fine}");
                // a rotated mask and a drifted stride: off the pixel grid
                assert!(!fine.contains("spectral nodes"), "{fine}");
                assert_eq!(last, BLUR_PASS_STAGE);
                assert_eq!(cal.uncertainty_fit, Some(Fit::SceneDetailPass));
            }
            DispersionModel::Subpixel => {
                assert_eq!(cal.stages.len(), 5);
                assert!(last.starts_with("texture fit"), "{last}");
            }
            DispersionModel::Rounded => assert_eq!(cal.stages.len(), 5),
        }
        let stated = |p: &Parameter| match model {
            DispersionModel::Subpixel
            | DispersionModel::DispersedMask
            | DispersionModel::CrispCells => true,
            DispersionModel::Rounded => {
                matches!(p, Parameter::Dx | Parameter::Dy | Parameter::ThetaDeg)
            }
        };
        assert!(
            Parameter::CALIBRATED
                .iter()
                .filter(|p| stated(p))
                .all(|&p| cal.uncertainty.get(p).is_some_and(|u| u > 0.0)),
            "{:?}",
            cal.uncertainty
        );
        // the texture fit (subpixel) also states 95 % half-widths, wider
        // than its standard errors; the rounded model states none
        for p in Parameter::CALIBRATED {
            match (model, cal.interval_95.get(p), cal.uncertainty.get(p)) {
                (
                    DispersionModel::Subpixel
                    | DispersionModel::DispersedMask
                    | DispersionModel::CrispCells,
                    Some(w),
                    Some(u),
                ) => {
                    assert!(w > u, "{p:?}: {w} ≤ {u}")
                }
                (DispersionModel::Rounded, None, _) => {}
                other => panic!("{p:?}: {other:?}"),
            }
        }
    }
}

/// On an aligned, blurred instrument the default's fine pass ends on the
/// pixel grid and runs again on its on-grid spectral nodes (every band of
/// 8 here); the answer stays aligned. The measurement is the discrete
/// operator's (`setup`): this tests the route; the pass's accuracy is
/// measured on the physical benchmark (`bench/results/default_stop59/`).
#[test]
fn the_fine_pass_refines_the_spectra_of_an_aligned_instrument() {
    let (y, mask) = aligned_blurred();
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::DispersedMask).unwrap();
    // the default, and the probe that runs again from the first run's answer
    for from_first_answer in [false, true] {
        let mut preset = DefaultPreset::default();
        let on_grid = preset
            .scene_fit
            .as_mut()
            .and_then(|s| s.fine_pass.as_mut())
            .and_then(|f| f.on_grid.as_mut())
            .expect("the default's on-grid nodes");
        on_grid.from_first_answer = from_first_answer;
        let cal = calibrate_default(&p, &preset, &mut |_| {}).unwrap();
        let fine = fine_pass_name(&cal);
        assert!(
            fine.contains("8 spectral nodes: the mask on the pixel grid"),
            "{fine}"
        );
        assert_stays_aligned(&cal.parameters);
        let e = cal.parameters;
        assert!((e.blur_sigma_px - 0.5).abs() < 0.05, "{e:?}");
    }
}

/// The name of the fine pass's stage in `cal`'s report.
fn fine_pass_name(cal: &cassi_core::calib::Calibration) -> &str {
    cal.stages
        .iter()
        .find(|s| s.name.starts_with("scene fit's fine pass"))
        .map(|s| s.name.as_str())
        .expect("the fine pass")
}

/// An aligned instrument blurred by σ 0.5 px: the discrete operator's
/// 96×96, 8-band measurement ([`setup`]).
fn aligned_blurred() -> (cassi_core::Measurement, cassi_core::Mask) {
    let truth = Mismatch {
        blur_sigma_px: 0.5,
        ..Mismatch::nominal(2.0)
    };
    setup(96, 8, truth, DispersionModel::DispersedMask)
}

/// The drifted prism's bounds above, around the aligned geometry (this
/// small 8-band problem pins α to about 0.25°, with or without the on-grid
/// nodes).
fn assert_stays_aligned(e: &Mismatch) {
    assert!(e.dx.abs() < 0.1 && e.dy.abs() < 0.1, "{e:?}");
    assert!(e.theta_deg.abs() < 0.15, "{e:?}");
    assert!(
        (e.a1 - 2.0).abs() < 0.02 && e.alpha_deg.abs() < 0.5,
        "{e:?}"
    );
}

/// The fine pass on GAP-TV's principal spectra (a probe, not the default)
/// runs where its settings ask, says so in its stage's name, and keeps an
/// aligned instrument aligned (the same bounds as the default's above; the
/// discrete operator's measurement: the route, not the accuracy — that is
/// the physical benchmark's, `bench/results/default_stop60/`).
#[test]
fn the_fine_pass_on_principal_spectra_keeps_an_aligned_instrument_aligned() {
    use cassi_core::calib::{FinePass, SceneFitSettings, SpectralBasis};
    let (y, mask) = aligned_blurred();
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::DispersedMask).unwrap();
    let settings = SceneFitSettings {
        fine_pass: Some(FinePass {
            spectral_basis: Some(SpectralBasis {
                components: 4,
                gap_iterations: 20,
            }),
            on_grid: None,
            ..FinePass::default()
        }),
        ..SceneFitSettings::default()
    };
    let preset = DefaultPreset {
        scene_fit: Some(settings),
        ..DefaultPreset::default()
    };
    let cal = calibrate_default(&p, &preset, &mut |_| {}).unwrap();
    let fine = fine_pass_name(&cal);
    assert!(fine.contains("4 principal spectra"), "{fine}");
    assert_stays_aligned(&cal.parameters);
    // a basis of more spectra than bands is refused by its own name
    let too_many = DefaultPreset {
        scene_fit: Some(SceneFitSettings {
            fine_pass: Some(FinePass {
                spectral_basis: Some(SpectralBasis {
                    components: 9,
                    gap_iterations: 20,
                }),
                ..FinePass::default()
            }),
            ..settings
        }),
        ..DefaultPreset::default()
    };
    let mut stages = 0;
    let err = calibrate_default(&p, &too_many, &mut |_| stages += 1).unwrap_err();
    assert!(
        err.to_string().contains("fine_pass.spectral_basis"),
        "{err}"
    );
    assert_eq!(stages, 0, "refused before any stage");
    // and a negative high-pass width, by its own name
    let negative = DefaultPreset {
        scene_fit: Some(SceneFitSettings {
            fine_pass: Some(FinePass {
                high_pass_px: Some(-1.0),
                ..FinePass::default()
            }),
            ..settings
        }),
        ..DefaultPreset::default()
    };
    let err = calibrate_default(&p, &negative, &mut |_| stages += 1).unwrap_err();
    assert!(err.to_string().contains("fine_pass.high_pass_px"), "{err}");
    assert_eq!(stages, 0, "refused before any stage");
}

/// A raised cancel flag stops either preset with `Cancelled` (no result
/// made from failed scores); raised mid-run (after the first stage), the
/// run ends with the same error instead of a result; a flag never raised
/// changes nothing.
#[test]
fn a_raised_cancel_flag_stops_a_calibration() {
    use cassi_core::CassiError;
    use cassi_core::calib::{Preset, calibrate};
    use std::sync::atomic::{AtomicBool, Ordering};

    let truth = Mismatch {
        dx: 0.7,
        ..Mismatch::nominal(2.0)
    };
    let (y, mask) = setup(64, 8, truth, DispersionModel::Subpixel);
    let raised = AtomicBool::new(true);
    for preset in ["default", "paper"] {
        let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::Subpixel)
            .unwrap()
            .with_cancel(&raised);
        let mut stages = 0;
        let e = calibrate(&p, &Preset::by_name(preset, 2.0).unwrap(), &mut |_| {
            stages += 1
        })
        .unwrap_err();
        assert!(matches!(e, CassiError::Cancelled { .. }), "{preset}: {e}");
    }

    // raised once the first stage has finished
    let flag = AtomicBool::new(false);
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::Subpixel)
        .unwrap()
        .with_cancel(&flag);
    let r = calibrate_default(&p, &DefaultPreset::default(), &mut |_| {
        flag.store(true, Ordering::Relaxed);
    });
    assert!(matches!(r, Err(CassiError::Cancelled { .. })), "{r:?}");
    // and an unraised flag changes nothing
    let quiet = AtomicBool::new(false);
    let free = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::Subpixel).unwrap();
    let a = calibrate_default(&free, &DefaultPreset::default(), &mut |_| {}).unwrap();
    let b = calibrate_default(
        &free.with_cancel(&quiet),
        &DefaultPreset::default(),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(a.parameters, b.parameters);
}

/// A preset whose detail pass has a width out of range (a settings file's)
/// is refused before any stage runs, naming the setting.
#[test]
fn a_bad_detail_pass_is_refused_before_the_work() {
    let (y, mask) = setup(
        32,
        8,
        Mismatch::nominal(2.0),
        DispersionModel::DispersedMask,
    );
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::DispersedMask).unwrap();
    let mut preset = DefaultPreset::default();
    let settings = preset.scene_fit.as_mut().unwrap();
    settings.detail_pass.as_mut().unwrap().detail_px = -2.0;
    let mut stages = 0;
    let e = calibrate_default(&p, &preset, &mut |_| stages += 1).unwrap_err();
    assert!(e.to_string().contains("detail_pass.detail_px"), "{e}");
    assert_eq!(stages, 0);
}

/// Checks that `cal`'s last stage is `stage`, gives the answer and moved σ
/// alone; returns the stage before's ψ and σ's error before and after it.
fn blur_moved_alone_last(cal: &Calibration, stage: &str, truth: &Mismatch) -> (Mismatch, f64, f64) {
    let [.., before, last] = cal.stages.as_slice() else {
        panic!("{} stages", cal.stages.len());
    };
    assert_eq!(last.name, stage);
    assert_eq!(cal.parameters, last.parameters);
    for q in Parameter::CALIBRATED {
        if q != Parameter::BlurSigmaPx {
            assert_eq!(q.get(&before.parameters), q.get(&last.parameters), "{q:?}");
        }
    }
    (
        before.parameters,
        before.parameters.blur_sigma_px - truth.blur_sigma_px,
        last.parameters.blur_sigma_px - truth.blur_sigma_px,
    )
}

/// The blur's bootstrap (opt-in) is the calibration's last stage and moves
/// σ alone, by the first pass's σ bias measured on GAP-TV's scene sent
/// back through the model. On data of the model's own operator (an inverse
/// crime: here the bootstrap's data and the measurement come alike, so its
/// bias estimate should be right) it at least halves the scene fit's σ
/// error (measured +0.036 → +0.004 px); a correction of the wrong sign
/// would double it.
#[test]
fn the_blur_bootstrap_moves_the_blur_alone() {
    let truth = Mismatch {
        dx: 0.4,
        dy: -0.3,
        blur_sigma_px: 0.6,
        ..Mismatch::nominal(2.0)
    };
    let model = DispersionModel::DispersedMask;
    let (y, mask) = setup(96, 8, truth, model);
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, model).unwrap();
    // the scene fit's σ, the one the bootstrap measures the bias of (not
    // the blur pass's, the default's last stage since stop 41)
    let preset = DefaultPreset {
        blur_bootstrap: Some(BlurBootstrap {
            through: model,
            ..BlurBootstrap::default()
        }),
        blur_pass: None,
        ..DefaultPreset::default()
    };
    let cal = calibrate_default(&p, &preset, &mut |_| {}).unwrap();
    let (before, was, now) = blur_moved_alone_last(&cal, BLUR_BOOTSTRAP_STAGE, &truth);
    // no blur pass: the operator reconstructs with the reported σ
    assert_eq!(cal.model_blur_sigma_px, None);
    assert_eq!(cal.reconstruction_parameters(), cal.parameters);
    eprintln!("σ error: scene fit {was:+.4}, bootstrapped {now:+.4}");
    assert!(was.abs() > 0.02, "the scene fit's own error {was:+.4}");
    assert!(now.abs() <= 0.5 * was.abs(), "{was:+.4} -> {now:+.4}");
    // below its guard the stage does not run: σ stays the scene fit's
    let guarded = DefaultPreset {
        blur_bootstrap: Some(BlurBootstrap {
            through: model,
            min_blur_px: 1.0,
            ..BlurBootstrap::default()
        }),
        blur_pass: None,
        ..DefaultPreset::default()
    };
    let cal = calibrate_default(&p, &guarded, &mut |_| {}).unwrap();
    let last = cal.stages.last().unwrap();
    assert_ne!(last.name, BLUR_BOOTSTRAP_STAGE);
    assert_eq!(cal.parameters, before);
}

/// The blur pass (the default's since stop 41) is the calibration's last stage and moves σ
/// alone, refitted on the crisp-cell model with GAP-TV's texture. On data
/// of the crisp-cell model's own operator (an inverse crime: the pass's
/// model made them, at a fractional row phase) it at least halves the
/// scene fit's σ error, fitted in the dispersed-mask model on a smooth
/// scene (measured −0.125 → −0.008 px). The calibrated model reconstructs
/// with the pass's σ (since stop 63); settings that say so, and settings
/// written before the choice, with its own fit's.
#[test]
fn the_blur_pass_moves_the_blur_alone() {
    let truth = Mismatch {
        dx: 0.4,
        dy: -0.3,
        blur_sigma_px: 0.6,
        ..Mismatch::nominal(2.0)
    };
    let (y, mask) = setup(96, 8, truth, DispersionModel::CrispCells);
    let model = DispersionModel::DispersedMask;
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, model).unwrap();
    let preset = DefaultPreset {
        blur_pass: Some(BlurPass::default()),
        ..DefaultPreset::default()
    };
    let cal = calibrate_default(&p, &preset, &mut |_| {}).unwrap();
    let (before, was, now) = blur_moved_alone_last(&cal, BLUR_PASS_STAGE, &truth);
    eprintln!("σ error: scene fit {was:+.4}, blur pass {now:+.4}");
    assert!(was.abs() > 0.02, "the scene fit's own error {was:+.4}");
    assert!(now.abs() <= 0.5 * was.abs(), "{was:+.4} -> {now:+.4}");
    // the pass started from the texture fit's σ (within the start's range):
    // the operator reconstructs with the reported σ, the pass's
    let texture = cal
        .stages
        .iter()
        .find(|s| s.name.starts_with("texture fit"))
        .expect("a texture stage");
    assert!(texture.parameters.blur_sigma_px <= TEXTURE_START_MAX_PX);
    assert_eq!(cal.model_blur_sigma_px, None);
    assert_eq!(cal.reconstruction_parameters(), cal.parameters);
    // the choice before stop 63: the calibrated model's own fit's σ, the
    // report the pass's, every estimate as with the default
    let own = DefaultPreset {
        blur_pass: Some(BlurPass {
            reconstruct_with: ReconstructionSigma::ModelFit,
            ..BlurPass::default()
        }),
        ..DefaultPreset::default()
    };
    let own = calibrate_default(&p, &own, &mut |_| {}).unwrap();
    assert_eq!(own.parameters, cal.parameters);
    assert_eq!(own.model_blur_sigma_px, Some(before.blur_sigma_px));
    assert_eq!(own.reconstruction_parameters(), before);
    // a pass without GAP-TV iterations is refused by its own name, before any stage
    let empty = DefaultPreset {
        blur_pass: Some(BlurPass {
            gap_iterations: 0,
            ..BlurPass::default()
        }),
        ..DefaultPreset::default()
    };
    let mut stages = 0;
    let e = calibrate_default(&p, &empty, &mut |_| stages += 1).unwrap_err();
    assert!(e.to_string().contains("blur_pass.gap_iterations"), "{e}");
    assert_eq!(stages, 0);
}

/// An aligned instrument (its mask on the pixel grid): the calibrated
/// model reconstructs with the reported σ plus the on-grid margin, every
/// reported estimate as without it; with the margin off, with the reported σ.
#[test]
fn an_aligned_instrument_reconstructs_with_the_on_grid_margin() {
    let truth = Mismatch {
        blur_sigma_px: 0.5,
        ..Mismatch::nominal(2.0)
    };
    let (y, mask) = setup(96, 8, truth, DispersionModel::CrispCells);
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, DispersionModel::DispersedMask).unwrap();
    let cal = calibrate_default(&p, &DefaultPreset::default(), &mut |_| {}).unwrap();
    let sigma = cal.parameters.blur_sigma_px;
    assert_eq!(cal.model_blur_sigma_px, None);
    assert_eq!(cal.on_grid_margin_px, Some(ON_GRID_MARGIN_PX));
    assert_eq!(
        cal.reconstruction_parameters(),
        Mismatch {
            blur_sigma_px: sigma + ON_GRID_MARGIN_PX,
            ..cal.parameters
        }
    );
    let off = DefaultPreset {
        blur_pass: Some(BlurPass {
            on_grid_margin: None,
            ..BlurPass::default()
        }),
        ..DefaultPreset::default()
    };
    let without = calibrate_default(&p, &off, &mut |_| {}).unwrap();
    assert_eq!(without.parameters, cal.parameters);
    assert_eq!(without.on_grid_margin_px, None);
    assert_eq!(without.reconstruction_parameters(), cal.parameters);
}

/// The texture fit's Nelder–Mead stops at `texture_evaluations` (its σ grid
/// of 11 scores before it); without one (the default) it has
/// `max_evaluations`, which lets it run on.
#[test]
fn the_texture_fit_keeps_to_its_budget() {
    let truth = drifted_prism();
    let model = DispersionModel::Subpixel;
    let (y, mask) = setup(96, 8, truth, model);
    let p = CalibrationProblem::nominal(&y, &mask, 8, 2.0, model).unwrap();
    let texture_evaluations = |budget: Option<usize>| {
        let preset = DefaultPreset {
            texture_evaluations: budget,
            ..DefaultPreset::default()
        };
        let cal = calibrate_default(&p, &preset, &mut |_| {}).unwrap();
        let stage = cal.stages.last().unwrap();
        assert!(stage.name.starts_with("texture fit"), "{}", stage.name);
        stage.evaluations
    };
    let (budget, grid) = (12, 11);
    assert!(texture_evaluations(Some(budget)) <= budget + grid);
    let by_default = texture_evaluations(None);
    assert!(by_default > budget + grid, "{by_default}");
    let max = DefaultPreset::default().max_evaluations;
    assert_eq!(by_default, texture_evaluations(Some(max)));
}
