//! Forward + adjoint timing of the CASSI operator. Writes JSON to
//! `bench/results/operator.json` (or $CASSI_BENCH_OUT).
//!
//! Run: `cargo bench -p cassi-core --bench operator`

mod common;

use std::time::Instant;

use cassi_core::optics::{Blurred, CassiOperator, Dispersion, DispersionModel, ModelOperator};
use cassi_core::{DispersionParams, Frame, LinearOperator, Mismatch, Rng};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn case(
    size: usize,
    bands: usize,
    params: DispersionParams,
    model: DispersionModel,
    blur_sigma_px: f64,
    runs: usize,
) -> serde_json::Value {
    let mut rng = Rng::new(1);
    let mask = Frame::from_vec(
        size,
        size,
        (0..size * size)
            .map(|_| (rng.uniform() < 0.5) as u8 as f32)
            .collect(),
    )
    .unwrap();
    // the models that sample the mask per band: built from the nominal
    // mask (no pose) through ModelOperator (the crisp-cell model's blur is
    // its own); the dispersed-mask model's band masks are stored at the
    // first adjoint (the warm-up), as in an iterative solver
    let op: Box<dyn LinearOperator> = if model.samples_mask_per_band() {
        let m = Mismatch {
            a1: params.a1,
            alpha_deg: params.alpha_deg,
            blur_sigma_px,
            ..Mismatch::nominal(params.a1)
        };
        Box::new(ModelOperator::new(&mask, bands, &m, model).unwrap())
    } else {
        let cassi =
            CassiOperator::new(mask, Dispersion::new(bands, params, model).unwrap()).unwrap();
        let (rows, cols) = cassi.measurement_shape();
        if blur_sigma_px > 0.0 {
            Box::new(Blurred::new(cassi, blur_sigma_px, rows, cols).unwrap())
        } else {
            Box::new(cassi)
        }
    };
    let x: Vec<f32> = (0..op.domain_len()).map(|_| rng.uniform() as f32).collect();
    let mut y = vec![0.0f32; op.range_len()];
    let mut back = vec![0.0f32; op.domain_len()];
    let (mut fwd, mut adj, mut pair) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..runs + 3 {
        let t0 = Instant::now();
        op.apply(&x, &mut y);
        let t1 = Instant::now();
        op.adjoint(&y, &mut back);
        let t2 = Instant::now();
        if i >= 3 {
            fwd.push((t1 - t0).as_secs_f64() * 1e3);
            adj.push((t2 - t1).as_secs_f64() * 1e3);
            pair.push((t2 - t0).as_secs_f64() * 1e3);
        }
    }
    std::hint::black_box(&back);
    // bytes a pair must move at least: read x, write x, read/write y once each
    let bytes = (2 * op.domain_len() + 2 * op.range_len()) * 4;
    let pair_ms = median(pair);
    let row = serde_json::json!({
        "size": format!("{size}x{size}x{bands}"),
        "model": model.name(),
        "blur_sigma_px": blur_sigma_px,
        "a1": params.a1, "alpha_deg": params.alpha_deg,
        "runs": runs,
        "forward_ms_median": median(fwd),
        "adjoint_ms_median": median(adj),
        "pair_ms_median": pair_ms,
        "effective_gb_per_s": bytes as f64 / pair_ms / 1e6,
    });
    eprintln!("{row}");
    row
}

fn main() {
    let path = common::record_path("operator.json");
    let nominal = DispersionParams {
        a1: 2.0,
        alpha_deg: 0.0,
        a2: 0.0,
    };
    let paper = DispersionParams {
        a1: 2.04,
        alpha_deg: 0.5,
        a2: 0.0,
    };
    let mut rows = Vec::new();
    for (size, runs) in [(256, 200), (660, 40)] {
        rows.push(case(size, 28, nominal, DispersionModel::Rounded, 0.0, runs));
        rows.push(case(size, 28, paper, DispersionModel::Rounded, 0.0, runs));
        rows.push(case(size, 28, paper, DispersionModel::Subpixel, 0.0, runs));
        rows.push(case(size, 28, paper, DispersionModel::Subpixel, 0.5, runs));
        rows.push(case(
            size,
            28,
            paper,
            DispersionModel::DispersedMask,
            0.0,
            runs,
        ));
        rows.push(case(
            size,
            28,
            paper,
            DispersionModel::DispersedMask,
            0.5,
            runs,
        ));
        rows.push(case(
            size,
            28,
            paper,
            DispersionModel::CrispCells,
            0.5,
            runs,
        ));
    }
    let cpu = common::cpu_name();
    let out = serde_json::json!({
        "benchmark": "CASSI operator forward + adjoint",
        "machine": { "cpu": cpu, "threads": rayon::current_num_threads() },
        "results": rows,
    });
    common::write_record(&path, &out);
}
