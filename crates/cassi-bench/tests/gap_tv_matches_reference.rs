//! GAP-TV agrees with the NumPy + scikit-image reference
//! (`bench/gap_tv_reference.py`, same settings) on the 10 CAVE scenes with the
//! TSA mask: per scene and on average within 0.05 dB. The reference PSNRs are
//! the ones the benchmark recorded in `bench/results/gap_tv_reference.json`.
//! Skips itself when `../shared/data` is absent (fails instead under
//! `CASSI_REQUIRE_SHARED_DATA=1`).

use cassi_core::Mismatch;
use cassi_core::metrics::psnr;
use cassi_core::optics::{CassiOperator, DispersionModel};
use cassi_core::recon::{Method, Model};
use cassi_core::solvers::{Silent, Strength};

#[test]
fn gap_tv_matches_the_numpy_reference_on_cave() {
    let Some(data) = cassi_io::shared_data::for_test(&["scenes"]) else {
        return;
    };
    let reference: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../bench/results/gap_tv_reference.json"
        ))
        .expect("bench/results/gap_tv_reference.json is committed"),
    )
    .unwrap();
    // The reference projects x onto x ≥ 0 inside the iterations, as GAP-TV
    // did before the default dropped it (bench/results/gap_projection.json):
    // this compares the same algorithm.
    let Method::GapTv {
        mut gap,
        tv_iterations,
    } = Method::by_name("gap-tv").unwrap()
    else {
        unreachable!()
    };
    gap.nonnegative = true;
    let method = Method::GapTv { gap, tv_iterations };
    // the recorded reference must have used our current settings
    let settings = &reference["settings"];
    assert_eq!(settings["iterations"].as_u64(), Some(gap.iterations as u64));
    assert_eq!(settings["inner"].as_u64(), Some(tv_iterations as u64));
    assert_eq!(settings["accelerate"].as_bool(), Some(gap.accelerate));
    let Strength::Constant { value } = gap.strength else {
        panic!("gap-tv default is a constant weight")
    };
    assert!(
        (settings["weight"].as_f64().unwrap() - value as f64).abs() < 1e-6,
        "reference weight differs"
    );

    let mask = cassi_io::load_frame(data.join("masks/tsa_simu_mask256.mat"), Some("mask")).unwrap();
    let nominal = Mismatch::nominal(2.0);
    let (mut ours_sum, mut ref_sum) = (0.0, 0.0);
    let rows = reference["scenes"].as_array().unwrap();
    assert_eq!(rows.len(), 10);
    for row in rows {
        let name = row["scene"].as_str().unwrap();
        let truth = cassi_io::load_cube(
            data.join(format!("scenes/{name}.npy")),
            None,
            cassi_io::CubeLayout::Auto,
        )
        .unwrap();
        let y = CassiOperator::with_mismatch(&mask, 28, &nominal, DispersionModel::Rounded)
            .unwrap()
            .forward(&truth)
            .unwrap();
        let model = Model::new(&mask, 28, 2.0, nominal, DispersionModel::Rounded).unwrap();
        let x = method
            .solve(&y, &model, &mut Silent)
            .unwrap()
            .cube
            .clipped_to_unit();
        let ours = psnr(&truth, &x).unwrap();
        let theirs = row["psnr"].as_f64().unwrap();
        assert!(
            (ours - theirs).abs() < 0.05,
            "{name}: cassi {ours:.4} dB, reference {theirs:.4} dB"
        );
        ours_sum += ours;
        ref_sum += theirs;
    }
    assert!((ours_sum - ref_sum).abs() / 10.0 < 0.05);
}
