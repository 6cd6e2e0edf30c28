//! cassi_core::metrics against scikit-image / numpy reference values.
//!
//! tests/data/metrics/reference.json comes from make_reference.py next to it
//! (scikit-image `peak_signal_noise_ratio`, `structural_similarity` with
//! Gaussian weights σ = 1.5 and population covariance, numpy SAM).

use cassi_core::Cube;
use cassi_core::metrics::{
    evaluate, psnr, psnr_band_mean, psnr_per_band, sam_deg, ssim, ssim_per_band,
};
use serde::Deserialize;

#[derive(Deserialize)]
struct Reference {
    scale: f64,
    cases: Vec<Case>,
}

/// Infinite PSNRs are written as JSON null.
#[derive(Deserialize)]
struct Case {
    name: String,
    shape: [usize; 3],
    truth_q: Vec<i64>,
    estimate_q: Vec<i64>,
    psnr: Option<f64>,
    psnr_per_band: Vec<Option<f64>>,
    psnr_band_mean: Option<f64>,
    ssim_per_band: Vec<f64>,
    ssim: f64,
    sam_deg: f64,
}

const PSNR_TOL: f64 = 1e-6; // dB
const SSIM_TOL: f64 = 1e-5;
const SAM_TOL: f64 = 1e-5; // degrees

fn load() -> Reference {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/metrics/reference.json"
    );
    let text = std::fs::read_to_string(path).expect("read reference.json");
    serde_json::from_str(&text).expect("parse reference.json")
}

fn cube(shape: [usize; 3], q: &[i64], scale: f64) -> Cube {
    // q / 2^20 is exact in f32.
    let data = q.iter().map(|&v| (v as f64 / scale) as f32).collect();
    Cube::from_vec(shape[0], shape[1], shape[2], data).unwrap()
}

fn check(what: &str, got: f64, want: Option<f64>, tol: f64, max: &mut f64) {
    match want {
        None => assert_eq!(got, f64::INFINITY, "{what}: want +inf, got {got}"),
        Some(w) => {
            let d = (got - w).abs();
            assert!(d <= tol, "{what}: got {got}, want {w} (diff {d:e})");
            *max = max.max(d);
        }
    }
}

#[test]
fn metrics_match_scikit_image() {
    let r = load();
    assert!(r.cases.len() >= 4);
    let (mut dp, mut ds, mut da) = (0.0f64, 0.0f64, 0.0f64);
    for c in &r.cases {
        let t = cube(c.shape, &c.truth_q, r.scale);
        let e = cube(c.shape, &c.estimate_q, r.scale);
        let n = &c.name;

        check(
            &format!("{n} psnr"),
            psnr(&t, &e).unwrap(),
            c.psnr,
            PSNR_TOL,
            &mut dp,
        );
        let per = psnr_per_band(&t, &e).unwrap();
        assert_eq!(per.len(), c.psnr_per_band.len());
        for (k, (g, w)) in per.iter().zip(&c.psnr_per_band).enumerate() {
            check(&format!("{n} psnr band {k}"), *g, *w, PSNR_TOL, &mut dp);
        }
        let pbm = psnr_band_mean(&t, &e).unwrap();
        check(
            &format!("{n} psnr_band_mean"),
            pbm,
            c.psnr_band_mean,
            PSNR_TOL,
            &mut dp,
        );

        let sp = ssim_per_band(&t, &e).unwrap();
        assert_eq!(sp.len(), c.ssim_per_band.len());
        for (k, (g, w)) in sp.iter().zip(&c.ssim_per_band).enumerate() {
            check(
                &format!("{n} ssim band {k}"),
                *g,
                Some(*w),
                SSIM_TOL,
                &mut ds,
            );
        }
        check(
            &format!("{n} ssim"),
            ssim(&t, &e).unwrap(),
            Some(c.ssim),
            SSIM_TOL,
            &mut ds,
        );

        let sam = sam_deg(&t, &e).unwrap();
        check(&format!("{n} sam"), sam, Some(c.sam_deg), SAM_TOL, &mut da);

        // evaluate() agrees with the single metrics bit for bit.
        let m = evaluate(&t, &e).unwrap();
        assert_eq!(m.psnr.to_bits(), psnr(&t, &e).unwrap().to_bits(), "{n}");
        assert_eq!(m.psnr_band_mean.to_bits(), pbm.to_bits(), "{n}");
        assert_eq!(m.ssim.to_bits(), ssim(&t, &e).unwrap().to_bits(), "{n}");
        assert_eq!(m.sam_deg.to_bits(), sam.to_bits(), "{n}");
    }
    eprintln!("max |diff| vs scikit-image: PSNR {dp:e} dB, SSIM {ds:e}, SAM {da:e} deg");
}

/// Timing on a CAVE/KAIST-sized cube; run with
/// `cargo test --release --test metrics_reference -- --ignored --nocapture`.
#[test]
#[ignore]
fn evaluate_timing_28x256x256() {
    let (l, h, w) = (28, 256, 256);
    let mut s = 0x1234_5678u32;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s as f32 / u32::MAX as f32
    };
    let t: Vec<f32> = (0..l * h * w).map(|_| next()).collect();
    let e: Vec<f32> = t
        .iter()
        .map(|v| (v + 0.1 * (next() - 0.5)).clamp(0.0, 1.0))
        .collect();
    let t = Cube::from_vec(l, h, w, t).unwrap();
    let e = Cube::from_vec(l, h, w, e).unwrap();
    let _ = evaluate(&t, &e).unwrap(); // warm-up (thread pool)
    let runs = 10;
    let mut best = f64::INFINITY;
    let start = std::time::Instant::now();
    for _ in 0..runs {
        let t0 = std::time::Instant::now();
        std::hint::black_box(evaluate(&t, &e).unwrap());
        best = best.min(t0.elapsed().as_secs_f64());
    }
    let mean = start.elapsed().as_secs_f64() / runs as f64;
    let t0 = std::time::Instant::now();
    std::hint::black_box(ssim(&t, &e).unwrap());
    let t_ssim = t0.elapsed().as_secs_f64();
    eprintln!(
        "evaluate 28×256×256: mean {:.1} ms, best {:.1} ms (ssim alone {:.1} ms, {} threads)",
        mean * 1e3,
        best * 1e3,
        t_ssim * 1e3,
        rayon::current_num_threads()
    );
}
