//! Locating and reading the PyTorch test vectors of `../shared/data/nets`,
//! found by `cassi_io::shared_data` (absent → the test prints a note and
//! passes, or fails under `CASSI_REQUIRE_SHARED_DATA=1`).
#![allow(dead_code)]

pub mod cave;
pub mod sha256;
pub mod torch_pickle;

use std::path::PathBuf;

use cassi_nets::Tensor;

/// The shared data's `nets` folder, or `None` after a note (the test skips).
pub fn nets_dir() -> Option<PathBuf> {
    cassi_io::shared_data::for_test(&["nets"]).map(|d| d.join("nets"))
}

/// A float32 .npy as a tensor of its NumPy shape.
pub fn npy(path: PathBuf) -> Tensor {
    let a = cassi_io::load_array(&path, None).unwrap_or_else(|e| panic!("{e}"));
    Tensor::new(a.shape, a.data).unwrap()
}

/// Max |a − b|, printed with the test vector's name (the report quotes it).
pub fn check(name: &str, got: &Tensor, want: &Tensor, tol: f32) -> f32 {
    assert_eq!(got.shape(), want.shape(), "{name}: shape");
    let d = got.max_abs_diff(want);
    eprintln!("{name}: max |Δ| = {d:.3e} (tolerance {tol:.0e})");
    assert!(d <= tol, "{name}: max |Δ| = {d:e} > {tol:e}");
    d
}

/// The MST inputs of README §1 (what `common/make_inputs.py` writes), from
/// `y.npy` (1, 256, 310) and `mask.npy` (256, 256) by the library's
/// [`cassi_nets::toolbox_inputs`].
pub fn mst_inputs(nets: &std::path::Path) -> (Tensor, Tensor) {
    let y = npy(nets.join("common/y.npy"));
    let mask = npy(nets.join("common/mask.npy"));
    let y = cassi_core::Measurement::from_vec(256, 310, y.into_data()).unwrap();
    let mask = cassi_core::Mask::from_vec(256, 256, mask.into_data()).unwrap();
    cassi_nets::toolbox_inputs(&y, &mask, 28, 2).unwrap()
}

/// Rows 0..rows of a (1, C, H, W) tensor (the reference dumps the top 32
/// rows of large activations).
pub fn top_rows(t: &Tensor, rows: usize) -> Tensor {
    let [_, c, h, w] = t.nchw("activation", None).unwrap();
    let mut data = Vec::with_capacity(c * rows * w);
    for ch in 0..c {
        data.extend_from_slice(&t.data()[ch * h * w..][..rows * w]);
    }
    Tensor::new(vec![1, c, rows, w], data).unwrap()
}

/// The 1-minute load average (benchmarks record it: other work on the
/// machine inflates times).
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}
