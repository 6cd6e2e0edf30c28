//! Cost of the calibration objective: one proxy score vs one exact gradient
//! (forward mode) along 1, 2 and 3 parameters, 256×256×28. This is the
//! measurement behind the choice of forward mode (see `calib::gradient`).
//! Writes JSON to `bench/results/calibration_score.json` (or
//! $CASSI_BENCH_OUT).
//!
//! Run: `cargo bench -p cassi-core --bench calibration_score`

mod common;

use cassi_core::Mismatch;
use cassi_core::calib::{CalibrationProblem, Parameter, ProxyParams};
use cassi_core::instrument::STANDARD_WAVELENGTHS_NM;
use cassi_core::optics::{DispersionModel, SimulationSpec, simulate};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};

fn main() {
    let path = common::record_path("calibration_score.json");
    let scene = synthetic_scene(&SceneSpec {
        rows: 256,
        cols: 256,
        wavelengths_nm: STANDARD_WAVELENGTHS_NM.to_vec(),
        seed: 1,
    })
    .unwrap();
    let mask = random_binary_mask(256, 256, 0.5, 1).unwrap();
    let model = DispersionModel::Rounded;
    let spec = SimulationSpec {
        mismatch: Mismatch::paper(),
        model,
        noise: None,
    };
    let y = simulate(&scene, &mask, &spec).unwrap();
    let problem = CalibrationProblem::nominal(&y, &mask, 28, 2.0, model).unwrap();
    let at = Mismatch {
        dx: 1.4,
        dy: 0.9,
        theta_deg: 0.25,
        ..Mismatch::nominal(2.0)
    };
    use Parameter::{Dx, Dy, ThetaDeg};
    let mut rows = Vec::new();
    for iterations in [8, 12, 15] {
        let proxy = ProxyParams {
            iterations,
            sigma: 0.7,
        };
        let score = common::median_ms(15, || {
            std::hint::black_box(problem.score(&at, &proxy).unwrap());
        });
        let mut row = serde_json::json!({ "iterations": iterations, "score_ms": score });
        for params in [&[Dx][..], &[Dy, ThetaDeg], &[Dx, Dy, ThetaDeg]] {
            let g = common::median_ms(7, || {
                std::hint::black_box(problem.score_and_gradient(&at, &proxy, params).unwrap());
            });
            row[format!("gradient_{}_ms", params.len())] = g.into();
            row[format!("gradient_{}_over_score", params.len())] = (g / score).into();
        }
        eprintln!("{row}");
        rows.push(row);
    }
    let cpu = common::cpu_name();
    let out = serde_json::json!({
        "benchmark": "calibration score vs forward-mode gradient (P parameters), 256x256x28, rounded model, σ 0.7",
        "machine": { "cpu": cpu, "threads": rayon::current_num_threads() },
        "results": rows,
    });
    common::write_record(&path, &out);
}
