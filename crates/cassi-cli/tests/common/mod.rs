//! What the CLI integration tests share: running the binary, scratch
//! folders, and the shape of a refusal.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn cassi(args: &[&str]) -> Output {
    cassi_env(args, &[])
}

/// Runs the binary with extra environment variables.
pub fn cassi_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cassi"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("the cassi binary runs")
}

/// A fresh, empty folder for one test of one test binary.
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Asserts that a run succeeded, showing its stderr if not.
pub fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs a command that must fail: exit code 1, stderr containing every
/// `needle`, no panic, and `output` not created.
pub fn assert_fails(args: &[&str], needles: &[&str], output: &Path) {
    let out = cassi(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "args {args:?}\nstderr: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    for n in needles {
        assert!(stderr.contains(n), "expected '{n}' in: {stderr}");
    }
    assert!(
        !output.exists(),
        "{} was written despite the error",
        output.display()
    );
}
