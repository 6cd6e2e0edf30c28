//! Cost of the scene fit's inner solve: one cold solve of the coarse scene
//! (`SceneFitSettings::cold_solve`, 60 CGLS iterations, tolerance 0 so every
//! run does all of them) at one ψ, for the real snapshots' size (660×660
//! mask, 28 bands, blur σ 0.6 px) and the benchmark's (256×256), with
//! 8-px cells (the fit's) and 4-px cells. The calibration's scene stage is
//! ~90 % such iterations. Writes JSON to `bench/results/scene_fit_solve.json`
//! (or $CASSI_BENCH_OUT). Built only on the crate's public API, so the same
//! file times an older commit side by side (`--label`).
//!
//! Run: `cargo bench -p cassi-core --bench scene_fit_solve [-- --label NAME]`

mod common;

use cassi_core::Mismatch;
use cassi_core::calib::{CalibrationProblem, SceneFitSettings, scene_fit_score};
use cassi_core::optics::{DispersionModel, ModelOperator};
use cassi_core::solvers::CglsParams;
use cassi_core::synth::random_binary_mask;

fn main() {
    let path = common::record_path("scene_fit_solve.json");
    let args: Vec<String> = std::env::args().collect();
    let label = args
        .iter()
        .position(|a| a == "--label")
        .and_then(|i| args.get(i + 1).cloned())
        .unwrap_or_else(|| "this commit".into());
    let bands = 28;
    let psi = Mismatch {
        dx: 0.3,
        dy: -0.2,
        theta_deg: 0.1,
        a1: 2.03,
        alpha_deg: 0.2,
        blur_sigma_px: 0.6,
        a2: 0.0,
    };
    let mut rows = Vec::new();
    for size in [660usize, 256] {
        let mask = random_binary_mask(size, size, 0.5, 11).unwrap();
        let model = DispersionModel::DispersedMask;
        // a measurement of the model's own shape: the solve's cost does not
        // depend on its values
        let op = ModelOperator::new(&mask, bands, &psi, model).unwrap();
        let (r, c) = op.measurement_shape();
        let values: Vec<f32> = (0..r * c)
            .map(|i| ((i * 7919) % 1000) as f32 / 1e3)
            .collect();
        let y = cassi_core::Measurement::from_vec(r, c, values).unwrap();
        let problem = CalibrationProblem::nominal(&y, &mask, bands, 2.0, model).unwrap();
        for cell_px in [8usize, 4] {
            let settings = SceneFitSettings {
                cell_px,
                cold_solve: CglsParams {
                    iterations: 60,
                    tolerance: 0.0,
                },
                ..SceneFitSettings::default()
            };
            let ms = common::median_ms(5, || {
                std::hint::black_box(scene_fit_score(&problem, &settings, &psi).unwrap());
            });
            let row = serde_json::json!({
                "size": size, "cell_px": cell_px, "cgls_iterations": 60,
                "solve_ms": ms, "per_iteration_ms": ms / 60.0,
            });
            eprintln!("{label}: {row}");
            rows.push(row);
        }
    }
    let cpu = common::cpu_name();
    let out = serde_json::json!({
        "benchmark": "scene fit: one cold solve (60 CGLS iterations) at one ψ, dispersed-mask model, 28 bands, σ 0.6 px",
        "label": label,
        "machine": { "cpu": cpu, "threads": rayon::current_num_threads() },
        "results": rows,
    });
    common::write_record(&path, &out);
}
