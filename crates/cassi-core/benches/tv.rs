//! Chambolle TV denoiser timing: the GAP-TV budget is 100 calls of
//! `denoise` with max_iter = 5 on a 256×256×28 cube. Writes JSON to
//! `bench/results/tv.json` (or $CASSI_BENCH_OUT).
//!
//! Run: `cargo bench -p cassi-core --bench tv`

mod common;

use std::time::Instant;

use cassi_core::denoise::{
    TvChambolleParams, TvScratch2d, TvScratch3d, tv_chambolle_2d, tv_chambolle_3d,
};
use cassi_core::{Cube, Rng};

/// (median, min) of the repetitions.
fn median_min(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0])
}

/// Smooth band-varying structure, piecewise-constant patches and noise, in [0, 1].
fn scene(bands: usize, size: usize) -> Cube {
    let mut rng = Rng::new(7);
    let mut c = Cube::zeros(bands, size, size);
    for k in 0..bands {
        for r in 0..size {
            for col in 0..size {
                let s = 0.5
                    + 0.3
                        * ((0.05 * r as f64 + 0.2 * k as f64).sin())
                        * ((0.07 * col as f64).cos())
                    + 0.2 * (((r / 16 + col / 24 + k) % 2) as f64)
                    + 0.1 * (rng.uniform() - 0.5);
                c.set(k, r, col, s.clamp(0.0, 1.0) as f32);
            }
        }
    }
    c
}

/// `reps` repetitions of `calls` denoise calls, each on a fresh copy of the
/// scene (as in a solver, the cube was just written: the copy is not timed);
/// returns the (median, min) over repetitions of the summed call times, in ms.
fn time_calls(den: &mut dyn FnMut(&mut Cube), x: &Cube, calls: usize, reps: usize) -> (f64, f64) {
    let mut work = x.clone();
    den(&mut work); // warm the scratch
    let mut totals = Vec::new();
    for _ in 0..reps {
        let mut total = 0.0;
        for _ in 0..calls {
            work.as_mut_slice().copy_from_slice(x.as_slice());
            let t0 = Instant::now();
            den(&mut work);
            total += t0.elapsed().as_secs_f64() * 1e3;
        }
        totals.push(total);
        std::hint::black_box(&work);
    }
    median_min(totals)
}

fn main() {
    let path = common::record_path("tv.json");
    let (bands, size) = (28, 256);
    let x = scene(bands, size);
    let voxels = (bands * size * size) as f64;
    let threads = rayon::current_num_threads();
    let weight = 0.1;
    let mut rows = Vec::new();

    let mut case = |name: &str,
                    kernels: &str,
                    den: &mut dyn FnMut(&mut Cube),
                    max_iter: usize,
                    calls: usize| {
        let (ms, ms_min) = time_calls(den, &x, calls, 5);
        let ns_px_it = ms * 1e6 / (calls as f64 * max_iter as f64 * voxels);
        let row = serde_json::json!({
            "denoiser": name,
            "kernels": kernels,
            "cube": format!("{size}x{size}x{bands}"),
            "weight": weight,
            "max_iter": max_iter,
            "calls": calls,
            "total_ms_median": ms,
            "total_ms_min": ms_min,
            "ms_per_call": ms / calls as f64,
            "ns_per_voxel_per_iteration": ns_px_it,
            "ns_per_voxel_per_iteration_per_core": ns_px_it * threads as f64,
        });
        eprintln!("{row}");
        rows.push(row);
    };

    #[cfg(target_arch = "x86_64")]
    let has_avx = std::arch::is_x86_feature_detected!("avx");
    #[cfg(not(target_arch = "x86_64"))]
    let has_avx = false;
    let avx = if has_avx {
        "avx (runtime-detected)"
    } else {
        "baseline"
    };
    for (max_iter, eps, calls) in [(5, 2e-4, 100), (50, 0.0, 10)] {
        let p = TvChambolleParams { max_iter, eps };
        for portable in [false, true] {
            let mut s = TvScratch2d::new();
            s.set_portable_only(portable);
            let mut den = |c: &mut Cube| tv_chambolle_2d(c, weight, &p, &mut s);
            let k = if portable { "baseline (sse2)" } else { avx };
            case("tv-chambolle-2d", k, &mut den, max_iter, calls);
            // every band ran all its iterations (no early stop flattering the time)
            assert!(s.iterations().iter().all(|&i| i == max_iter));
        }
    }
    let p = TvChambolleParams {
        max_iter: 5,
        eps: 2e-4,
    };
    for portable in [false, true] {
        let mut s = TvScratch3d::new();
        s.set_portable_only(portable);
        let mut den = |c: &mut Cube| tv_chambolle_3d(c, weight, 1.0, &p, &mut s);
        let k = if portable { "baseline (sse2)" } else { avx };
        case("tv-chambolle-3d (mu=1)", k, &mut den, 5, 20);
        assert_eq!(s.iterations(), 5);
    }

    let cpu = common::cpu_name();
    let out = serde_json::json!({
        "benchmark": "Chambolle TV denoising (skimage-exact): the GAP-TV budget is 100 calls x max_iter 5 on 256x256x28 in <= 600 ms",
        "budget_ms": 600.0,
        "note": "total_ms_median sums 100 (or `calls`) calls; ns per voxel per iteration counts max_iter iterations per call (the first computes only the gradient, the last only the output)",
        "machine": { "cpu": cpu, "threads": threads },
        "results": rows,
    });
    common::write_record(&path, &out);
}
