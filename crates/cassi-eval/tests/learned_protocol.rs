//! The protocol with a network (feature `nets`, official MST-S weights from
//! ../shared/data): MST-S is guided by the nominal mask in II, the
//! calibrated one in III and the true one in IV, so on a measurement made
//! through a moved mask IV beats II by a wide margin and III comes close
//! to IV. The weights are read once, when loaded. Skips without
//! ../shared/data (fails under `CASSI_REQUIRE_SHARED_DATA=1`).
#![cfg(feature = "nets")]

use std::path::Path;

use cassi_core::calib::Preset;
use cassi_core::optics::{DispersionModel, NoiseModel};
use cassi_core::{Cube, Mismatch};
use cassi_eval::method::{LearnedMethod, StudyMethod};
use cassi_eval::protocol::{Scenario, Study, run_scene};

/// MST-S loaded from a copy of `weights` that is deleted right after: the
/// study must run on the model loaded here, not read the file again.
fn loaded_from_a_copy(weights: &Path) -> LearnedMethod {
    let copy = std::env::temp_dir().join(format!("cassi-eval-mst_s-{}.pth", std::process::id()));
    std::fs::copy(weights, &copy).unwrap_or_else(|e| panic!("{}: {e}", weights.display()));
    let loaded = LearnedMethod::new(cassi_core::recon::MethodId::MstS, &copy, None).load();
    std::fs::remove_file(&copy).unwrap();
    loaded.unwrap_or_else(|e| panic!("{e:#}"))
}

#[test]
fn mst_s_is_guided_by_each_scenarios_mask() {
    let Some(data) = cassi_io::shared_data::for_test(&["nets"]) else {
        return;
    };
    let common = data.join("nets/common");
    let scene: Cube =
        cassi_io::load_cube(common.join("cube.npy"), None, cassi_io::CubeLayout::Auto)
            .unwrap_or_else(|e| panic!("{e}"));
    let mask =
        cassi_io::load_frame(common.join("mask.npy"), None).unwrap_or_else(|e| panic!("{e}"));
    let study = Study {
        // a moved mask with the nominal dispersion: only the mask separates II from IV
        mismatch: Mismatch {
            dx: 1.5,
            dy: 1.0,
            theta_deg: 0.3,
            a1: 2.0,
            alpha_deg: 0.0,
            ..Mismatch::nominal(2.0)
        },
        instrument: DispersionModel::Rounded,
        noise: NoiseModel::default(),
        preset: Preset::by_name("default", 2.0).unwrap(),
        methods: vec![StudyMethod::Learned(loaded_from_a_copy(
            &data.join("weights/mst_s.pth"),
        ))],
        stride: 2.0,
    };
    let (r, _) = run_scene("reference", &scene, &mask, &study, 0, false, &mut |_| {}).unwrap();
    let p = |s| r.outcome("mst-s", s).unwrap().metrics.psnr;
    let (ideal, assumed, corrected, oracle) = (
        p(Scenario::IdealClean),
        p(Scenario::Assumed),
        p(Scenario::Corrected),
        p(Scenario::Oracle),
    );
    eprintln!(
        "MST-S: I {ideal:.2}, II {assumed:.2}, III {corrected:.2}, IV {oracle:.2} dB; calibration errors {:?}",
        r.errors
    );
    // measured: I 26.79, II 18.88, III 26.28, IV 26.35 dB
    assert!(oracle > assumed + 5.0, "IV {oracle} vs II {assumed}");
    assert!(corrected > oracle - 0.5, "III {corrected} vs IV {oracle}");
    assert!(ideal > assumed, "I {ideal} vs II {assumed}");
}
