//! Property test over every reader (issue #12): small valid files of each
//! format (.npy, .npz stored and deflated, MAT v5 plain and compressed, MAT
//! v7.3) are truncated, have bytes flipped, and have header fields
//! overwritten with big numbers; `describe` and `load_array` must not
//! panic, must stay within a bounded peak allocation (counting global
//! allocator), and must give an error or a well-formed finite array.
//!
//! Own test binary: it lowers the process-wide element budget to 2^20 so
//! that a mutation that still decodes is cheap, which other tests (which
//! check the default budget's messages) must not see.

mod common;

use std::path::PathBuf;

use cassi_io::{describe, load_array, save_array};
use common::TempDir;
use common::alloc::{MIB, peak_during};
use proptest::prelude::*;

#[global_allocator]
static ALLOC: common::alloc::Counting = common::alloc::Counting;

const LIMIT: usize = 64 * MIB;

/// (extension, bytes) of the valid seeds.
fn seeds() -> &'static [(&'static str, Vec<u8>)] {
    static SEEDS: std::sync::OnceLock<Vec<(&'static str, Vec<u8>)>> = std::sync::OnceLock::new();
    SEEDS.get_or_init(|| {
        let dir = TempDir::new("fuzz-seeds");
        let data: Vec<f32> = (0..60).map(|i| i as f32 * 0.25 - 3.0).collect();
        let mut out = Vec::new();
        for ext in ["npy", "npz", "mat"] {
            let p = dir.join(&format!("a.{ext}"));
            save_array(&p, "a", &[3, 4, 5], &data).unwrap();
            out.push((ext, std::fs::read(&p).unwrap()));
        }
        let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        for (ext, f) in [
            ("mat", "tests/data/v5_types_compressed.mat"),
            ("npz", "tests/data/arrays.npz"),
            ("npy", "tests/data/cube_f64_f.npy"),
            ("mat", "tests/fixtures/valid73.mat"),
            ("mat", "tests/fixtures/half.mat"),
        ] {
            out.push((ext, std::fs::read(manifest.join(f)).unwrap()));
        }
        out
    })
}

#[derive(Debug, Clone)]
enum Mutation {
    Truncate(usize),
    Flip(usize, u8),
    /// Overwrite 2, 4 or 8 bytes with a big number (little- or big-endian).
    Big(usize, u64, u8, bool),
    /// Replace a run of ASCII digits (a .npy shape) with a big number.
    Digits(usize, u64),
}

fn big() -> impl Strategy<Value = u64> {
    prop_oneof![
        Just(u32::MAX as u64),
        Just(i32::MAX as u64),
        Just(1u64 << 30),
        Just(1u64 << 20),
        Just(1u64 << 16),
        Just(u64::MAX),
        Just(1u64 << 40),
        any::<u64>(),
    ]
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Flip(i, b)),
        (any::<usize>(), big(), 0u8..3, any::<bool>())
            .prop_map(|(i, v, w, be)| Mutation::Big(i, v, w, be)),
        (any::<usize>(), big()).prop_map(|(i, v)| Mutation::Digits(i, v)),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let n = bytes.len();
    if n == 0 {
        return;
    }
    match *m {
        Mutation::Truncate(i) => bytes.truncate(i % n),
        Mutation::Flip(i, b) => bytes[i % n] ^= b.max(1),
        Mutation::Big(i, v, w, be) => {
            let w = [2, 4, 8][w as usize];
            let at = i % n;
            let src = if be { v.to_be_bytes() } else { v.to_le_bytes() };
            let src = if be { &src[8 - w..] } else { &src[..w] };
            for (k, &b) in src.iter().enumerate().take(n - at) {
                bytes[at + k] = b;
            }
        }
        Mutation::Digits(i, v) => {
            let digits: Vec<usize> = (0..n).filter(|&k| bytes[k].is_ascii_digit()).collect();
            if let Some(&at) = digits.get(i % digits.len().max(1)) {
                let mut end = at;
                while end < n && bytes[end].is_ascii_digit() {
                    end += 1;
                }
                bytes.splice(at..end, v.to_string().into_bytes());
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn mutated_files_never_panic_and_allocate_boundedly(
        which in 0usize..8,
        muts in proptest::collection::vec(mutation(), 1..4),
    ) {
        cassi_core::limits::set_max_elements(1 << 20);
        let (ext, seed) = &seeds()[which];
        let mut bytes = seed.clone();
        for m in &muts {
            apply(&mut bytes, m);
        }
        let dir = TempDir::new("fuzz");
        let p = dir.join(&format!("m.{ext}"));
        std::fs::write(&p, &bytes).unwrap();
        let name = p.display().to_string();
        let (r, peak) = peak_during(|| describe(&p));
        prop_assert!(peak <= LIMIT, "describe: peak {} for {:?}", peak, muts);
        if let Err(e) = &r {
            prop_assert!(e.to_string().starts_with(&name), "{}", e);
        }
        for var in [None, Some("a"), Some("cube")] {
            let (r, peak) = peak_during(|| load_array(&p, var));
            prop_assert!(peak <= LIMIT, "load {:?}: peak {} for {:?}", var, peak, muts);
            match r {
                Ok(a) => {
                    prop_assert_eq!(a.data.len(), a.shape.iter().product::<usize>());
                    prop_assert!(a.data.iter().all(|v| v.is_finite()));
                }
                Err(e) => prop_assert!(e.to_string().starts_with(&name), "{}", e),
            }
        }
    }
}

#[test]
fn the_seeds_themselves_load() {
    for (ext, bytes) in seeds() {
        let dir = TempDir::new("seed");
        let p = dir.join(&format!("s.{ext}"));
        std::fs::write(&p, bytes).unwrap();
        let s = describe(&p).unwrap_or_else(|e| panic!("{e}"));
        assert!(!s.variables.is_empty());
    }
}
