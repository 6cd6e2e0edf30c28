//! Locating and reading the PyTorch test vectors of `../shared/data/nets`.
//! Same rule as cassi-io's shared-data test: `$CASSI_SHARED_DATA`, else
//! `<crate>/../../../shared/data`; absent → the test prints a note and passes.
#![allow(dead_code)]

use std::path::PathBuf;

use cassi_nets::Tensor;

pub fn shared_data() -> Option<PathBuf> {
    let dir = match std::env::var_os("CASSI_SHARED_DATA") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    };
    dir.is_dir().then_some(dir)
}

/// `shared_data()/nets`, or `None` after printing why the test skips.
pub fn nets_dir(test: &str) -> Option<PathBuf> {
    let dir = shared_data().map(|d| d.join("nets")).filter(|d| d.is_dir());
    if dir.is_none() {
        eprintln!("note: {test}: no shared data directory (set CASSI_SHARED_DATA); skipping");
    }
    dir
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

/// The MST inputs of README §1, as `common/make_inputs.py` builds them from
/// `y.npy` (1, 256, 310) and `mask.npy` (256, 256): H (1, 28, 256, 256) with
/// H[c, r, j] = (y / 28 · 2)[r, 2c + j] (division first, in f32), and
/// Phi (1, 28, 256, 310) with Phi[c, r, 2c + j] = mask[r, j].
pub fn mst_inputs(nets: &std::path::Path) -> (Tensor, Tensor) {
    let y = npy(nets.join("common/y.npy"));
    let mask = npy(nets.join("common/mask.npy"));
    let (bands, n, wy) = (28, 256, 310);
    assert_eq!(y.shape(), [1, n, wy]);
    assert_eq!(mask.shape(), [n, n]);
    let ys: Vec<f32> = y.data().iter().map(|v| (v / 28.0) * 2.0).collect();
    let mut h = vec![0.0f32; bands * n * n];
    let mut phi = vec![0.0f32; bands * n * wy];
    for c in 0..bands {
        for r in 0..n {
            h[(c * n + r) * n..][..n].copy_from_slice(&ys[r * wy + 2 * c..][..n]);
            phi[(c * n + r) * wy + 2 * c..][..n].copy_from_slice(&mask.data()[r * n..][..n]);
        }
    }
    (
        Tensor::new(vec![1, bands, n, n], h).unwrap(),
        Tensor::new(vec![1, bands, n, wy], phi).unwrap(),
    )
}

/// Rows 0..rows of a (C, H, W) feature map as a (1, C, rows, W) tensor
/// (the reference dumps the top 32 rows of large activations).
pub fn top_rows(f: &cassi_nets::FeatureMap, rows: usize) -> Tensor {
    let mut data = Vec::with_capacity(f.c * rows * f.w);
    for c in 0..f.c {
        data.extend_from_slice(&f.data[c * f.h * f.w..][..rows * f.w]);
    }
    Tensor::new(vec![1, f.c, rows, f.w], data).unwrap()
}

/// A whole feature map as a (1, C, H, W) tensor.
pub fn batch_of_one(f: &cassi_nets::FeatureMap) -> Tensor {
    Tensor::new(vec![1, f.c, f.h, f.w], f.data.clone()).unwrap()
}
