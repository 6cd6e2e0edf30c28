//! PnP-HSICNN plumbing with the seeded HSI-SDeCNN test-vector weights (the
//! pretrained PnP-CASSI denoiser is not in ../shared): the iterations run
//! the scheduled denoisers in order, a TV-only schedule is exactly
//! cassi-core's GAP-TV, and the network stages change the result.

mod common;

use cassi_core::optics::{DispersionModel, SimulationSpec, simulate};
use cassi_core::recon::{Method, Model, Reconstructor};
use cassi_core::solvers::{GapParams, Silent, Strength};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Cube, Mask, Measurement, Mismatch};
use cassi_nets::{DenoiserSchedule, PnpHsicnn, PnpHsicnnParams, Stage};
use common::nets_dir;

fn case(size: usize, bands: usize) -> (Cube, Mask, Measurement) {
    let scene = synthetic_scene(&SceneSpec {
        rows: size,
        cols: size,
        wavelengths_nm: (0..bands).map(|k| 450.0 + 20.0 * k as f64).collect(),
        seed: 3,
    })
    .unwrap();
    let mask = random_binary_mask(size, size, 0.5, 5).unwrap();
    let spec = SimulationSpec {
        mismatch: Mismatch::nominal(2.0),
        model: DispersionModel::Rounded,
        noise: None,
    };
    let y = simulate(&scene, &mask, &spec).unwrap();
    (scene, mask, y)
}

fn load(nets: &std::path::Path, params: PnpHsicnnParams) -> PnpHsicnn {
    PnpHsicnn::load(nets.join("hsi_sdecnn/hsi_sdecnn_seed0.safetensors"), params)
        .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_papers_124_iterations_run_the_papers_schedule() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let (_, mask, y) = case(10, 9);
    let params = PnpHsicnnParams::default();
    assert_eq!(params.gap.iterations, 124);
    assert_eq!(params.schedule, DenoiserSchedule::PAPER);
    assert_eq!(params.sigma, 10.0 / 255.0);
    let mut pnp = load(&nets, params);
    let nominal = Mismatch::nominal(2.0);
    let r = pnp
        .solve(
            &y,
            &Model::new(&mask, 9, 2.0, nominal, DispersionModel::Rounded).unwrap(),
            &mut Silent,
        )
        .unwrap();
    assert_eq!(r.stages, DenoiserSchedule::PAPER.stages(124));
    assert_eq!(r.reconstruction.solution_iterations, 124);
    assert_eq!(r.reconstruction.cube.shape(), (9, 10, 10));
    assert!(
        r.reconstruction
            .cube
            .as_slice()
            .iter()
            .all(|v| v.is_finite())
    );
}

#[test]
fn tv_only_is_gap_tv_and_the_network_stages_change_the_result() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let (_, mask, y) = case(16, 8);
    let calibrated = Mismatch {
        dx: 0.4,
        dy: -0.3,
        theta_deg: 0.2,
        a1: 2.0,
        alpha_deg: 0.0,
        ..Mismatch::nominal(2.0)
    };
    let gap = GapParams {
        iterations: 12,
        strength: Strength::Constant { value: 0.05 },
        ..GapParams::default()
    };
    let tv_only = PnpHsicnnParams {
        gap,
        schedule: DenoiserSchedule {
            warmup: 12,
            dnn_per_cycle: 1,
            tv_per_cycle: 1,
        },
        ..PnpHsicnnParams::default()
    };
    let run = |params: PnpHsicnnParams| {
        load(&nets, params)
            .solve(
                &y,
                &Model::new(&mask, 8, 2.0, calibrated, DispersionModel::Rounded).unwrap(),
                &mut Silent,
            )
            .unwrap()
    };
    let a = run(tv_only);
    assert!(a.stages.iter().all(|&s| s == Stage::Tv));
    let gap_tv = Method::GapTv {
        gap,
        tv_iterations: 5,
    }
    .solve(
        &y,
        &Model::new(&mask, 8, 2.0, calibrated, DispersionModel::Rounded).unwrap(),
        &mut Silent,
    )
    .unwrap();
    assert_eq!(a.reconstruction.cube, gap_tv.cube);
    assert_eq!(a.reconstruction.relative_residual, gap_tv.relative_residual);
    // the same recipe behind the method-agnostic interface
    let mut boxed: Box<dyn Reconstructor> = Box::new(load(&nets, tv_only));
    assert_eq!(boxed.name(), "pnp-hsicnn");
    let model = Model::new(&mask, 8, 2.0, calibrated, DispersionModel::Rounded).unwrap();
    let cube = boxed.reconstruct(&y, &model, &mut Silent).unwrap();
    assert_eq!(cube, a.reconstruction.cube);

    let mixed = PnpHsicnnParams {
        schedule: DenoiserSchedule {
            warmup: 6,
            dnn_per_cycle: 2,
            tv_per_cycle: 1,
        },
        ..tv_only
    };
    let b = run(mixed);
    use Stage::{Dnn, Tv};
    assert_eq!(
        b.stages,
        [Tv, Tv, Tv, Tv, Tv, Tv, Dnn, Dnn, Tv, Dnn, Dnn, Tv]
    );
    let diff = b
        .reconstruction
        .cube
        .as_slice()
        .iter()
        .zip(a.reconstruction.cube.as_slice())
        .map(|(p, q)| (p - q).abs())
        .fold(0.0f32, f32::max);
    assert!(
        diff > 1e-3,
        "network stages changed nothing (max |Δ| {diff})"
    );
}

#[test]
fn bad_settings_and_shapes_are_errors() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let (_, mask, y) = case(8, 4);
    let nominal = Mismatch::nominal(2.0);
    let bad_sigma = PnpHsicnnParams {
        sigma: -1.0,
        ..PnpHsicnnParams::default()
    };
    let e = load(&nets, bad_sigma)
        .solve(
            &y,
            &Model::new(&mask, 4, 2.0, nominal, DispersionModel::Rounded).unwrap(),
            &mut Silent,
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("sigma"), "{e}");
    let other_rows = Mask::from_vec(9, 8, vec![1.0; 72]).unwrap();
    let e = load(&nets, PnpHsicnnParams::default())
        .solve(
            &y,
            &Model::new(&other_rows, 4, 2.0, nominal, DispersionModel::Rounded).unwrap(),
            &mut Silent,
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("rows"), "{e}");
}
