//! Regression tests for issue #12 (item 3) on checkpoints, with a counting
//! global allocator: a tiny .pth whose strided view claims 2^30 elements is
//! refused before anything is materialised, a strict load never decodes a
//! tensor the network does not want, and a property test mutates small
//! valid .pth and .safetensors files (truncations, flipped bytes, header
//! fields overwritten with big numbers) and asserts no panic, a bounded peak
//! allocation, and an error or a well-formed map.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::path::PathBuf;

use cassi_nets::{HsiSdecnn, NetError, TensorMap};
use common::torch_pickle::{c_strides, pickle_int, pickle_str};
use proptest::prelude::*;

// ---- counting allocator (per thread: tests run in parallel) ----

struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn add(n: isize) {
    let _ = LIVE.try_with(|l| {
        let v = l.get() + n;
        l.set(v);
        let _ = PEAK.try_with(|p| {
            if v > p.get() {
                p.set(v)
            }
        });
    });
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            add(layout.size() as isize);
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            add(layout.size() as isize);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        add(-(layout.size() as isize));
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            add(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

const MIB: usize = 1 << 20;
const LIMIT: usize = 64 * MIB;

fn peak_during<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(|l| l.get());
    PEAK.with(|p| p.set(base));
    let r = f();
    (r, (PEAK.with(|p| p.get()) - base).max(0) as usize)
}

// ---- hand-made checkpoints ----

struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let p =
            std::env::temp_dir().join(format!("cassi-nets-hostile-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        Self(p)
    }
    fn file(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// name, shape, stride, storage element count (f32).
type Spec<'a> = (&'a str, Vec<usize>, Vec<usize>, usize);

/// The zip torch.save writes for an OrderedDict of float tensors.
fn pth_bytes(tensors: &[Spec]) -> Vec<u8> {
    let mut p = vec![0x80, 2];
    p.extend(b"ccollections\nOrderedDict\n)R(");
    for (i, (name, shape, stride, numel)) in tensors.iter().enumerate() {
        pickle_str(&mut p, name);
        p.extend(b"ctorch._utils\n_rebuild_tensor_v2\n((");
        pickle_str(&mut p, "storage");
        p.extend(b"ctorch\nFloatStorage\n");
        pickle_str(&mut p, &i.to_string());
        pickle_str(&mut p, "cpu");
        pickle_int(&mut p, *numel);
        p.extend(b"tQ");
        pickle_int(&mut p, 0);
        p.push(b'(');
        shape.iter().for_each(|&d| pickle_int(&mut p, d));
        p.extend(b"t(");
        stride.iter().for_each(|&d| pickle_int(&mut p, d));
        p.extend(b"t\x89ccollections\nOrderedDict\n)RtR");
    }
    p.extend(b"u.");
    let mut z = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    z.start_file("a/data.pkl", opts).unwrap();
    z.write_all(&p).unwrap();
    for (i, (_, _, _, numel)) in tensors.iter().enumerate() {
        z.start_file(format!("a/data/{i}"), opts).unwrap();
        let vals: Vec<u8> = (0..*numel)
            .flat_map(|k| (k as f32 * 0.5).to_le_bytes())
            .collect();
        z.write_all(&vals).unwrap();
    }
    z.finish().unwrap().into_inner()
}

fn safetensors_bytes(tensors: &[(&str, Vec<usize>)]) -> Vec<u8> {
    let mut header = serde_json::Map::new();
    let mut data = Vec::new();
    for (name, shape) in tensors {
        let begin = data.len();
        let n: usize = shape.iter().product();
        data.extend((0..n).flat_map(|k| (k as f32).to_le_bytes()));
        header.insert(
            name.to_string(),
            serde_json::json!({"dtype": "F32", "shape": shape, "data_offsets": [begin, data.len()]}),
        );
    }
    let h = serde_json::to_vec(&serde_json::Value::Object(header)).unwrap();
    let mut bytes = (h.len() as u64).to_le_bytes().to_vec();
    bytes.extend(h);
    bytes.extend(data);
    bytes
}

#[test]
fn tiny_pth_with_a_strided_2_pow_30_view_is_refused_before_materialising() {
    let dir = TempDir::new("strided");
    let p = dir.file("strided.pth");
    // One stored element, viewed (stride 0) as 32768 × 32768 = 2^30 elements.
    std::fs::write(&p, pth_bytes(&[("w", vec![32768, 32768], vec![0, 0], 1)])).unwrap();
    let size = std::fs::metadata(&p).unwrap().len();
    let (r, peak) = peak_during(|| TensorMap::load(&p));
    let msg = r.unwrap_err().to_string();
    eprintln!(
        "strided.pth ({size} bytes): peak {:.3} MiB; {msg}",
        peak as f64 / MIB as f64
    );
    assert!(size < 1024, "{size}");
    assert!(peak <= LIMIT, "{peak}");
    for n in [
        "strided.pth",
        "tensor w",
        "32768×32768",
        "1073741824",
        "over the budget of 33554432",
    ] {
        assert!(msg.contains(n), "no {n:?} in: {msg}");
    }
    // The same through a network's loader.
    let (r, peak) = peak_during(|| HsiSdecnn::load(&p));
    assert!(peak <= LIMIT, "{peak}");
    assert!(matches!(r, Err(NetError::Checkpoint { .. })));
}

#[test]
fn strict_load_checks_names_and_shapes_before_decoding_values() {
    let dir = TempDir::new("strict");
    let p = dir.file("big.pth");
    // A within-budget 2^25-element view of one element, under a name the
    // network does not want, and a mis-shaped one: decoding either would
    // cost 128 MiB.
    let big = vec![4096, 8192];
    std::fs::write(
        &p,
        pth_bytes(&[
            ("extra", big.clone(), vec![0, 0], 1),
            ("model.0.weight", big, vec![0, 0], 1),
        ]),
    )
    .unwrap();
    let (r, peak) = peak_during(|| {
        let m = TensorMap::load(&p)?;
        assert_eq!(m.parameter_count(), 2 << 25);
        HsiSdecnn::from_tensors(m)
    });
    let msg = r.err().unwrap().to_string();
    eprintln!(
        "big.pth strict load: peak {:.1} MiB",
        peak as f64 / MIB as f64
    );
    // What remains is the network itself built on zero-filled stand-ins
    // (~35 MiB); decoding either tensor would cost 128 MiB.
    assert!(peak <= LIMIT, "{peak}");
    assert!(msg.contains("unexpected: extra [4096, 8192]"), "{msg}");
    assert!(
        msg.contains("wrong shape: model.0.weight: got [4096, 8192], wanted [128, 29, 3, 3]"),
        "{msg}"
    );
}

#[test]
fn tensor_names_from_files_are_escaped_in_errors() {
    let dir = TempDir::new("escape");
    let p = dir.file("names.safetensors");
    std::fs::write(&p, safetensors_bytes(&[("\u{1b}[2Jw\u{7}", vec![2])])).unwrap();
    let msg = HsiSdecnn::load(&p).err().unwrap().to_string();
    assert!(msg.contains("unexpected: \\u{1b}[2Jw\\u{7} [2]"), "{msg}");
    assert!(!msg.contains('\u{1b}') && !msg.contains('\u{7}'), "{msg:?}");
    let q = dir.file("bad.safetensors");
    let mut bytes = safetensors_bytes(&[("\u{1b}]0;x\u{7}", vec![2])]);
    bytes.truncate(bytes.len() - 1);
    std::fs::write(&q, &bytes).unwrap();
    let msg = TensorMap::load(&q).err().unwrap().to_string();
    assert!(msg.contains("\\u{1b}]0;x"), "{msg}");
    assert!(!msg.contains('\u{1b}'), "{msg:?}");
}

// ---- property test over mutated checkpoints ----

fn valid_files() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        (
            "pth",
            pth_bytes(&[
                ("w", vec![2, 3], vec![1, 2], 6),
                ("b", vec![4], vec![1], 4),
                ("s", vec![3, 3], c_strides(&[3, 3]), 9),
            ]),
        ),
        (
            "safetensors",
            safetensors_bytes(&[("w", vec![2, 3]), ("b", vec![4])]),
        ),
    ]
}

#[derive(Debug, Clone)]
enum Mutation {
    Truncate(usize),
    Flip(usize, u8),
    /// Overwrite 4 or 8 bytes at a place with a big number.
    Big(usize, u64, bool),
    /// Replace a run of ASCII digits (a shape, an offset) with a big number.
    Digits(usize, u64),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let big = prop_oneof![
        Just(u32::MAX as u64),
        Just(i32::MAX as u64),
        Just(1u64 << 30),
        Just(1u64 << 25),
        Just(u64::MAX),
        Just(1u64 << 40),
        any::<u64>(),
    ];
    prop_oneof![
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Flip(i, b)),
        (any::<usize>(), big.clone(), any::<bool>()).prop_map(|(i, v, w)| Mutation::Big(i, v, w)),
        (any::<usize>(), big).prop_map(|(i, v)| Mutation::Digits(i, v)),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let n = bytes.len();
    match *m {
        Mutation::Truncate(i) => bytes.truncate(i % n),
        Mutation::Flip(i, b) => bytes[i % n] ^= b.max(1),
        Mutation::Big(i, v, wide) => {
            let w = if wide { 8 } else { 4 };
            let at = i % n.saturating_sub(w).max(1);
            let src = v.to_le_bytes();
            let k = w.min(n - at);
            bytes[at..at + k].copy_from_slice(&src[..k]);
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
    #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn mutated_checkpoints_never_panic_and_allocate_boundedly(
        which in 0usize..2,
        muts in proptest::collection::vec(mutation(), 1..4),
    ) {
        let dir = TempDir::new(&format!("prop-{:?}", std::thread::current().id()).replace(['(', ')'], ""));
        let (ext, mut bytes) = valid_files().swap_remove(which);
        for m in &muts {
            if !bytes.is_empty() {
                apply(&mut bytes, m);
            }
        }
        let p = dir.file(&format!("m.{ext}"));
        std::fs::write(&p, &bytes).unwrap();
        let (r, peak) = peak_during(|| TensorMap::load(&p));
        prop_assert!(peak <= LIMIT, "peak {} for {:?}", peak, muts);
        // A map that loads must be well formed: decode every tensor (when
        // small enough: a stride-0 view may legitimately be large).
        if let Ok(m) = &r
            && m.parameter_count() <= 1 << 22
        {
            let mut n = 0;
            for (_, t) in m.iter() {
                prop_assert_eq!(t.tensor.numel(), t.tensor.shape().iter().product::<usize>());
                n += t.tensor.numel();
            }
            prop_assert_eq!(n, m.parameter_count());
        }
        if let Err(e) = r {
            prop_assert!(e.to_string().contains(&format!("m.{ext}")), "{}", e);
        }
    }
}
