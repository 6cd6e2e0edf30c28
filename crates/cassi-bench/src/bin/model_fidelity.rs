//! How faithful each model family is to the physical instrument, with the
//! scene known: measurements from the 4× oversampled simulator (crisp mask
//! squares, continuous dispersion, Gaussian blur, no noise) at the
//! calibration benchmark's tuning-half ψ (seeds 14000 + 20·scene + slot,
//! slots 0–1), and per dispersion model
//!
//! * the relative residual min_s ‖y − s·A_ψ x‖ / ‖y‖ at the TRUE ψ (model
//!   error: what no calibration can fit away), and
//! * the scene-known fit: ψ minimising that residual (Nelder–Mead from the
//!   truth, two legs) — how far the family's best ψ sits from the truth;
//!
//! plus the cost of building each model's operator and of one forward
//! (median of 30, 256×256×28, ψ with blur).
//!
//! Why: the subpixel model interpolates the mask twice (the pose warp on
//! the mask grid, then the dispersion's split of the coded band), the
//! dispersed-mask model once where each band lands, as a camera integrates
//! the crisp mask; the crisp-cell model also blurs each side of a pixel's
//! mask edge from where it lies. Tuning-half scenes only: this is a model
//! study, not a held-out figure.
//!
//! Run: `cargo run --release -p cassi-bench --bin model_fidelity [-- --scenes N]`
//! → `bench/results/model_fidelity.json` (or $CASSI_BENCH_OUT).

use std::time::Instant;

use anyhow::Result;
use cassi_bench::{
    median, physical_random_mismatch, predict_on_detector, psi_of, relative_residual2,
};
use cassi_core::calib::nelder_mead;
use cassi_core::linop::LinearOperator;
use cassi_core::optics::{DispersionModel, ModelOperator, PhysicalSpec, simulate_physical};
use cassi_core::{Cube, Mask, Mismatch, Parameter, STANDARD_WAVELENGTHS_NM};
use cassi_eval::machine::Machine;
use serde_json::{Value, json};

const DETECTOR: (usize, usize) = (256, 310);
const SEED_BASE: u64 = 14_000;
const SLOTS: u64 = 2;
const FIT_STEPS: [f64; 6] = [0.1, 0.1, 0.05, 0.005, 0.1, 0.1];
const FIT_EVALS: usize = 300;
const TIMING_REPEATS: usize = 30;

fn per_parameter(f: impl Fn(Parameter) -> f64) -> Value {
    Value::Object(
        Parameter::CALIBRATED
            .iter()
            .map(|&p| (p.key().to_string(), json!(f(p))))
            .collect(),
    )
}

fn scene_known_fit(
    y: &[f64],
    mask: &Mask,
    scene: &Cube,
    truth: &Mismatch,
    model: DispersionModel,
) -> Value {
    let objective = |x: &[f64]| {
        predict_on_detector(mask, scene, &psi_of(truth, x), model, DETECTOR)
            .map_or(f64::INFINITY, |m| relative_residual2(y, &m))
    };
    let tol: Vec<f64> = FIT_STEPS.iter().map(|s| s * 1e-3).collect();
    let mut x: Vec<f64> = Parameter::CALIBRATED.iter().map(|p| p.get(truth)).collect();
    let mut f = objective(&x);
    for _ in 0..2 {
        let (xn, fnew, _) = nelder_mead(objective, &x, &FIT_STEPS, FIT_EVALS, &tol, 1e-14);
        if fnew < f {
            (x, f) = (xn, fnew);
        }
    }
    let est = psi_of(truth, &x);
    json!({
        "error": per_parameter(|p| p.get(&est) - p.get(truth)),
        "relative_residual_at_fit": f.sqrt(),
    })
}

fn timing(mask: &Mask, scene: &Cube, model: DispersionModel) -> Value {
    let psi = Mismatch {
        dx: 0.37,
        dy: -1.2,
        theta_deg: 0.4,
        a1: 2.03,
        alpha_deg: 0.5,
        blur_sigma_px: 0.5,
        a2: 0.0,
    };
    let mut build = Vec::new();
    let mut forward = Vec::new();
    for _ in 0..TIMING_REPEATS {
        let t = Instant::now();
        let op = ModelOperator::new(mask, scene.bands(), &psi, model).expect("a valid ψ");
        build.push(t.elapsed().as_secs_f64() * 1e3);
        let mut y = vec![0.0f32; op.range_len()];
        let t = Instant::now();
        op.apply(scene.as_slice(), &mut y);
        forward.push(t.elapsed().as_secs_f64() * 1e3);
    }
    json!({ "build_ms_median": median(build), "forward_ms_median": median(forward) })
}

fn main() -> Result<()> {
    let cassi_bench::ModelStudy { out, mask, scenes } =
        cassi_bench::model_study("model_fidelity", 3)?;
    let mut cases = Vec::new();
    let mut first_scene = None;
    for (index, path) in scenes.iter().enumerate() {
        let scene = cassi_io::load_cube(path, None, cassi_io::CubeLayout::Auto)?;
        for slot in 0..SLOTS {
            let seed = SEED_BASE + 20 * index as u64 + slot;
            let truth = physical_random_mismatch(seed);
            let spec = PhysicalSpec {
                oversample: 4,
                blur_sigma_px: truth.blur_sigma_px,
                detector: Some(DETECTOR),
                ..PhysicalSpec::default()
            };
            let y =
                simulate_physical(&scene, &mask, &STANDARD_WAVELENGTHS_NM, &truth, &spec, None)?;
            let y: Vec<f64> = y.as_slice().iter().map(|&v| v as f64).collect();
            let mut models = serde_json::Map::new();
            for model in [
                DispersionModel::Subpixel,
                DispersionModel::DispersedMask,
                DispersionModel::CrispCells,
            ] {
                let at_truth = predict_on_detector(&mask, &scene, &truth, model, DETECTOR)
                    .map(|m| relative_residual2(&y, &m).sqrt());
                let fit = scene_known_fit(&y, &mask, &scene, &truth, model);
                eprintln!(
                    "{} seed {seed} {:<15} residual at truth {:.4}  fit {}",
                    path.display(),
                    model.name(),
                    at_truth.unwrap_or(f64::NAN),
                    fit["error"]
                );
                models.insert(
                    model.name().into(),
                    json!({ "relative_residual_at_truth": at_truth, "scene_known_fit": fit }),
                );
            }
            cases.push(json!({
                "scene": path.file_stem().map(|s| s.to_string_lossy().into_owned()),
                "seed": seed,
                "truth": per_parameter(|p| p.get(&truth)),
                "models": models,
            }));
        }
        first_scene.get_or_insert(scene);
    }
    let scene = first_scene.ok_or_else(|| anyhow::anyhow!("no scenes"))?;
    let timings: serde_json::Map<String, Value> = DispersionModel::ALL
        .iter()
        .map(|&m| (m.name().to_string(), timing(&mask, &scene, m)))
        .collect();
    let record = json!({
        "benchmark": "model fidelity against the 4× oversampled physical simulator, scene known",
        "machine": Machine::this(),
        "instrument": { "oversample": 4, "detector": DETECTOR, "noise": "none",
                        "mismatch": "the calibration benchmark's tuning-half random ψ, slots 0–1" },
        "cases": cases,
        "timing_256x256x28": timings,
    });
    cassi_bench::write_record(&out, &record)?;
    eprintln!("wrote {out}");
    Ok(())
}
