//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod alloc;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Path of a fixture in `tests/data` (made by `tests/data/make_fixtures.py`).
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// A fresh directory under the system temp dir, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        static N: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "cassi-io-test-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
    /// Names of the entries in the directory, sorted.
    pub fn entries(&self) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The fixture value at index (i, j, k): 100 i + 10 j + k.
pub fn idx3(i: usize, j: usize, k: usize) -> f32 {
    (100 * i + 10 * j + k) as f32
}

/// C-order data of shape (a, b, c) holding 100 i + 10 j + k.
pub fn idx3_data(a: usize, b: usize, c: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(a * b * c);
    for i in 0..a {
        for j in 0..b {
            for k in 0..c {
                v.push(idx3(i, j, k));
            }
        }
    }
    v
}

/// Asserts that `r` is an error whose message contains every needle (and the path).
pub fn assert_err<T: std::fmt::Debug>(
    r: Result<T, cassi_io::IoError>,
    path: &Path,
    needles: &[&str],
) -> cassi_io::IoError {
    let e = r.expect_err("expected an error");
    let msg = e.to_string();
    assert!(
        msg.contains(&path.display().to_string()),
        "message does not name the file {}: {msg}",
        path.display()
    );
    assert_eq!(e.path(), path, "IoError::path()");
    for n in needles {
        assert!(msg.contains(n), "message lacks {n:?}: {msg}");
    }
    e
}
