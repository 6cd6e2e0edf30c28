//! cassi_core::denoise::tv against scikit-image's `denoise_tv_chambolle`.
//!
//! tests/data/tv/reference.json comes from make_reference.py next to it
//! (scikit-image 0.26, numpy 2.x, float32). Arrays are stored exactly as f32
//! bit patterns. "2d" cases: `channel_axis=0` (per band) = TvChambolle2d;
//! "3d" cases: `channel_axis=None` on the cube = TvChambolle3d with μ = 1.

use cassi_core::Cube;
use cassi_core::denoise::{
    Denoiser, TvChambolle2d, TvChambolle3d, TvChambolleParams, TvScratch2d, TvScratch3d,
    tv_chambolle_2d, tv_chambolle_3d,
};
use serde::Deserialize;
use std::collections::HashMap;

#[derive(Deserialize)]
struct Input {
    shape: [usize; 3],
    hex: String,
}

#[derive(Deserialize, Debug)]
#[serde(untagged)]
enum Iterations {
    PerBand(Vec<usize>),
    Global(usize),
}

#[derive(Deserialize)]
struct Case {
    input: String,
    kind: String,
    weight: f32,
    max_iter: usize,
    eps: f32,
    iterations: Iterations,
    output_hex: String,
}

#[derive(Deserialize)]
struct Reference {
    inputs: HashMap<String, Input>,
    cases: Vec<Case>,
}

const TOL: f32 = 1e-5;

fn load() -> Reference {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/tv/reference.json");
    let text = std::fs::read_to_string(path).expect("read reference.json");
    serde_json::from_str(&text).expect("parse reference.json")
}

fn parse_hex(s: &str) -> Vec<f32> {
    assert_eq!(s.len() % 8, 0);
    (0..s.len() / 8)
        .map(|i| f32::from_bits(u32::from_str_radix(&s[8 * i..8 * i + 8], 16).unwrap()))
        .collect()
}

fn cube_of(input: &Input) -> Cube {
    let [l, h, w] = input.shape;
    Cube::from_vec(l, h, w, parse_hex(&input.hex)).unwrap()
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Both compiled kernel sets (AVX where the CPU has it, and baseline SSE2).
#[test]
fn matches_scikit_image() {
    let r = load();
    assert!(r.cases.len() >= 6);
    for portable in [false, true] {
        let mut s2 = TvScratch2d::new();
        let mut s3 = TvScratch3d::new();
        s2.set_portable_only(portable);
        s3.set_portable_only(portable);
        for case in &r.cases {
            let input = &r.inputs[&case.input];
            let want = parse_hex(&case.output_hex);
            let params = TvChambolleParams {
                max_iter: case.max_iter,
                eps: case.eps,
            };
            let mut cube = cube_of(input);
            let label = format!(
                "{} {} w={} n={} (baseline kernels only: {portable})",
                case.input, case.kind, case.weight, case.max_iter
            );
            match (case.kind.as_str(), &case.iterations) {
                ("2d", Iterations::PerBand(iters)) => {
                    tv_chambolle_2d(&mut cube, case.weight, &params, &mut s2);
                    assert_eq!(s2.iterations(), &iters[..], "{label}: iterations per band");
                }
                ("3d", Iterations::Global(iters)) => {
                    tv_chambolle_3d(&mut cube, case.weight, 1.0, &params, &mut s3);
                    assert_eq!(s3.iterations(), *iters, "{label}: iterations");
                }
                _ => panic!("{label}: unknown case kind"),
            }
            let d = max_abs_diff(cube.as_slice(), &want);
            eprintln!("{label}: iterations {:?}, max |Δ| = {d:e}", case.iterations);
            assert!(d <= TOL, "{label}: max |Δ| = {d:e} > {TOL:e}");
        }
    }
}

/// The Denoiser objects are thin wrappers over the functions.
#[test]
fn denoiser_wrappers_match_functions() {
    let r = load();
    let input = &r.inputs["a"];
    let params = TvChambolleParams {
        max_iter: 7,
        eps: 2e-4,
    };
    let mut a = cube_of(input);
    let mut b = a.clone();
    let mut d2 = TvChambolle2d::new(params);
    d2.denoise(&mut a, 0.2);
    tv_chambolle_2d(&mut b, 0.2, &params, &mut TvScratch2d::new());
    assert_eq!(a, b);
    assert_eq!(d2.name(), "tv-chambolle-2d");
    assert_eq!(d2.iterations(), &[7, 7, 7]);

    let mut a = cube_of(input);
    let mut b = a.clone();
    let mut d3 = TvChambolle3d::new(params, 0.5);
    d3.denoise(&mut a, 0.2);
    let mut s3 = TvScratch3d::new();
    tv_chambolle_3d(&mut b, 0.2, 0.5, &params, &mut s3);
    assert_eq!(a, b);
    assert_eq!(d3.name(), "tv-chambolle-3d");
    assert_eq!(d3.iterations(), s3.iterations());
    assert!((2..=7).contains(&s3.iterations()));
}
