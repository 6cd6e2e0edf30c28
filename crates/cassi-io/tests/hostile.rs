//! Regression tests for issue #12 (items 3 and 7): tiny hostile files must
//! not cost gigabytes, `describe` reads headers only, names from files are
//! escaped, float16 HDF5 is reported as such, a truncated .npz names its
//! member. Each hostile file is made by the test (the HDF5 ones are tiny
//! committed fixtures, see `tests/fixtures/make_hostile_h5.py`), and the
//! peak of bytes allocated during each call is measured by a counting
//! global allocator.

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};

use cassi_io::{IoError, describe, load_array, save_array};
use common::TempDir;
use common::alloc::{MIB, peak_during};

#[global_allocator]
static ALLOC: common::alloc::Counting = common::alloc::Counting;

/// Peak allocation allowed for any call on a hostile file.
const LIMIT: usize = 64 * MIB;

fn hostile_fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// Runs `f`, prints and checks its peak allocation, returns its result.
fn bounded<T>(what: &str, f: impl FnOnce() -> T) -> T {
    let (r, peak) = peak_during(f);
    eprintln!("{what}: peak {:.2} MiB allocated", peak as f64 / MIB as f64);
    assert!(peak <= LIMIT, "{what}: peak {peak} bytes > {LIMIT}");
    r
}

/// `n` zero bytes after `prefix`, zlib- or raw-deflate-compressed.
fn deflated_zeros(prefix: &[u8], n: usize, mut w: impl Write) {
    w.write_all(prefix).unwrap();
    let z = vec![0u8; 1 << 20];
    let mut left = n;
    while left > 0 {
        let k = left.min(z.len());
        w.write_all(&z[..k]).unwrap();
        left -= k;
    }
}

fn npy_header(descr: &str, shape: &str) -> Vec<u8> {
    let mut text = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + text.len() + 1) % 64 != 0 {
        text.push(' ');
    }
    text.push('\n');
    let mut h = b"\x93NUMPY\x01\x00".to_vec();
    h.extend((text.len() as u16).to_le_bytes());
    h.extend(text.as_bytes());
    h
}

fn assert_budget_error(e: &IoError, path: &Path, needles: &[&str]) {
    let msg = e.to_string();
    assert!(matches!(e, IoError::Core { .. }), "{e:?}");
    for n in [
        &path.display().to_string()[..],
        "too large",
        "over the budget of 33554432",
    ]
    .iter()
    .chain(needles)
    {
        assert!(msg.contains(n), "no {n:?} in: {msg}");
    }
}

#[test]
fn never_written_1gib_hdf5_dataset_is_refused_not_materialised() {
    let p = hostile_fixture("unwritten.mat");
    assert!(std::fs::metadata(&p).unwrap().len() < 4096);
    for var in ["big", "bigc"] {
        let e = bounded(&format!("load unwritten.mat:{var}"), || {
            load_array(&p, Some(var)).unwrap_err()
        });
        let msg = e.to_string();
        eprintln!("{msg}");
        for n in [
            "unwritten.mat",
            &format!("variable '{var}'"),
            "1024×1024×128 double",
            "declares 134217728 elements but stores none",
        ] {
            assert!(msg.contains(n), "no {n:?} in: {msg}");
        }
    }
    let s = bounded("describe unwritten.mat", || describe(&p).unwrap());
    let text = s.to_string();
    eprintln!("{text}");
    for v in &s.variables {
        match v.name.as_str() {
            "big" | "bigc" => {
                assert_eq!(v.shape, [1024, 1024, 128]);
                assert!(v.stats.is_none());
                let why = v.stats_skipped.as_deref().unwrap();
                assert!(why.contains("stores none"), "{why}");
            }
            _ => assert_eq!(v.stats.as_ref().unwrap().max, Some(5.0)),
        }
    }
    assert!(text.contains("stats skipped"), "{text}");
    // The small written variable beside them still loads.
    assert_eq!(
        load_array(&p, Some("ok")).unwrap().data,
        [0., 2., 4., 1., 3., 5.]
    );
}

#[test]
fn npz_of_zeros_declaring_more_than_the_budget_is_refused_before_inflating() {
    let dir = TempDir::new("npz-bomb");
    let p = dir.join("zeros.npz");
    {
        let f = std::fs::File::create(&p).unwrap();
        let mut z = zip::ZipWriter::new(f);
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .large_file(true);
        z.start_file("z.npy", opts).unwrap();
        // float64 (16384, 8192): 2^27 elements, 1 GiB of zeros.
        deflated_zeros(&npy_header("<f8", "(16384, 8192)"), 1 << 30, &mut z);
        z.finish().unwrap();
    }
    let size = std::fs::metadata(&p).unwrap().len();
    eprintln!("zeros.npz: {size} bytes");
    let e = bounded("load zeros.npz", || load_array(&p, None).unwrap_err());
    eprintln!("{e}");
    assert_budget_error(&e, &p, &["variable 'z'", "16384×8192", "134217728"]);
    let s = bounded("describe zeros.npz", || describe(&p).unwrap());
    assert_eq!(s.variables[0].shape, [16384, 8192]);
    assert!(s.variables[0].stats.is_none());
    assert!(
        s.variables[0]
            .stats_skipped
            .as_deref()
            .unwrap()
            .contains("budget")
    );
}

/// A MAT v5 file holding one miCOMPRESSED double `name` of `dims` whose
/// values are stored as miUINT8 zeros (as MATLAB does for small integers).
fn zlib_mat(path: &Path, name: &str, dims: [u32; 2]) {
    let count = dims[0] as usize * dims[1] as usize;
    let pad8 = |n: usize| n.div_ceil(8) * 8;
    let mut el = Vec::new();
    let put = |v: &mut Vec<u8>, x: u32| v.extend(x.to_le_bytes());
    let payload = 16 + 16 + 8 + pad8(name.len()) + 8 + pad8(count);
    put(&mut el, 14);
    put(&mut el, payload as u32);
    for x in [6, 8, 6, 0, 5, 8, dims[0], dims[1], 1, name.len() as u32] {
        put(&mut el, x);
    }
    el.extend(name.as_bytes());
    el.resize(el.len() + pad8(name.len()) - name.len(), 0);
    put(&mut el, 2); // miUINT8
    put(&mut el, count as u32);
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    deflated_zeros(&el, pad8(count), &mut z);
    let z = z.finish().unwrap();
    let mut out = b"MATLAB 5.0 MAT-file, written by a cassi-io test".to_vec();
    out.resize(116, b' ');
    out.extend([0u8; 8]);
    out.extend([0, 1, b'I', b'M']);
    put(&mut out, 15);
    put(&mut out, z.len() as u32);
    out.extend(z);
    std::fs::write(path, out).unwrap();
}

#[test]
fn small_zlib_mat_inflating_to_gigabytes_is_refused_before_inflating() {
    let dir = TempDir::new("mat-bomb");
    let p = dir.join("bomb.mat");
    // 32768×32768 double stored as uint8 zeros: 1 GiB inflated (8 GiB as f64).
    zlib_mat(&p, "meas", [32768, 32768]);
    let size = std::fs::metadata(&p).unwrap().len();
    eprintln!("bomb.mat: {size} bytes");
    assert!(size < 2 << 20);
    let e = bounded("load bomb.mat", || {
        load_array(&p, Some("meas")).unwrap_err()
    });
    eprintln!("{e}");
    assert_budget_error(
        &e,
        &p,
        &["variable 'meas'", "32768×32768 double", "1073741824"],
    );
    let s = bounded("describe bomb.mat", || describe(&p).unwrap());
    assert_eq!(s.variables[0].shape, [32768, 32768]);
    assert!(s.variables[0].stats_skipped.is_some());

    // Within the budget, a compressed variable still loads (and costs its f32 size).
    let q = dir.join("ok.mat");
    zlib_mat(&q, "meas", [1000, 2000]);
    let a = bounded("load ok.mat", || load_array(&q, None).unwrap());
    assert_eq!(
        (a.shape.as_slice(), a.data.len()),
        (&[1000, 2000][..], 2_000_000)
    );
    assert!(a.data.iter().all(|&v| v == 0.0));
    let s = bounded("describe ok.mat", || describe(&q).unwrap());
    assert_eq!(s.variables[0].stats.as_ref().unwrap().count, 2_000_000);
}

#[test]
fn escape_sequences_in_variable_names_are_shown_escaped() {
    let dir = TempDir::new("escape");
    // A MAT v5 file whose variable name is ESC [ 2 J (clear screen) + "ab".
    let p = dir.join("names.mat");
    save_array(&p, "aaaaaaa", &[2, 2], &[1.0, 2.0, 3.0, 4.0]).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    let at = bytes.windows(7).position(|w| w == b"aaaaaaa").unwrap();
    bytes[at..at + 7].copy_from_slice(b"\x1b[2Jab\x07");
    std::fs::write(&p, &bytes).unwrap();
    // An .npz whose member name sets the terminal title.
    let q = dir.join("names.npz");
    {
        let mut z = zip::ZipWriter::new(std::fs::File::create(&q).unwrap());
        z.start_file(
            "\u{1b}]0;pwned\u{7}\u{202e}x.npy",
            zip::write::SimpleFileOptions::default(),
        )
        .unwrap();
        z.write_all(&npy_header("<f4", "(2,)")).unwrap();
        z.write_all(&[0u8; 8]).unwrap();
        z.finish().unwrap();
    }
    let mut texts = Vec::new();
    for f in [&p, &q] {
        texts.push(describe(f).unwrap().to_string());
        texts.push(load_array(f, Some("nope")).unwrap_err().to_string());
    }
    for t in &texts {
        eprintln!("{t}");
        assert!(
            !t.chars()
                .any(|c| c.is_control() && c != '\n' || c == '\u{202e}'),
            "raw control characters in: {t:?}"
        );
    }
    assert!(texts[0].contains("\\u{1b}[2Jab\\u{7}"), "{}", texts[0]);
    assert!(
        texts[1].contains("'\\u{1b}[2Jab\\u{7}' 2×2 single"),
        "{}",
        texts[1]
    );
    assert!(
        texts[2].contains("\\u{1b}]0;pwned\\u{7}\\u{202e}x"),
        "{}",
        texts[2]
    );
    assert!(texts[3].contains("\\u{1b}]0;pwned"), "{}", texts[3]);
    // The raw name still selects the variable (escaping is for display only).
    let a = load_array(&p, Some("\u{1b}[2Jab\u{7}")).unwrap();
    assert_eq!(a.data, [1.0, 2.0, 3.0, 4.0]);
}

#[test]
fn float16_hdf5_is_reported_and_read_as_half() {
    let p = hostile_fixture("half.mat");
    let s = describe(&p).unwrap();
    let v = &s.variables[0];
    assert_eq!((v.name.as_str(), v.dtype.as_str()), ("h", "float16"));
    assert!(s.to_string().contains("float16"), "{s}");
    let st = v.stats.as_ref().unwrap();
    assert_eq!((st.min, st.max), (Some(-2.0), Some(65504.0)));
    let a = load_array(&p, None).unwrap();
    assert_eq!(a.shape, [2, 3]);
    assert_eq!(a.data, [0.5, 65504.0, 0.0, -2.0, 1.0, 3.0]);
}

#[test]
fn truncated_npz_names_the_truncated_member() {
    let dir = TempDir::new("npz-cut");
    let p = dir.join("two.npz");
    {
        let mut z = zip::ZipWriter::new(std::fs::File::create(&p).unwrap());
        for (name, n) in [("first.npy", 16usize), ("second.npy", 4000)] {
            z.start_file(name, zip::write::SimpleFileOptions::default())
                .unwrap();
            z.write_all(&npy_header("<f4", &format!("({n},)"))).unwrap();
            let vals: Vec<u8> = (0..n).flat_map(|i| (i as f32).to_le_bytes()).collect();
            z.write_all(&vals).unwrap();
        }
        z.finish().unwrap();
    }
    let full = std::fs::read(&p).unwrap();
    let cut = dir.join("cut.npz");
    std::fs::write(&cut, &full[..full.len() * 2 / 3]).unwrap();
    for r in [
        describe(&cut).map(|_| ()),
        load_array(&cut, Some("first")).map(|_| ()),
    ] {
        let e = r.unwrap_err();
        let msg = e.to_string();
        eprintln!("{msg}");
        assert!(matches!(e, IoError::Truncated { .. }), "{e:?}");
        assert!(
            msg.contains("cut.npz") && msg.contains("member 'second.npy' is truncated"),
            "{msg}"
        );
        assert!(!msg.contains("i/o error"), "{msg}");
    }
    // Cut after the last member's data: the central directory is what is missing.
    let second_end = full.len() - 2 * 46 - 22 - "first.npy".len() - "second.npy".len();
    std::fs::write(&cut, &full[..second_end]).unwrap();
    let msg = describe(&cut).unwrap_err().to_string();
    assert!(
        msg.contains("after member 'second.npy'") && msg.contains("central directory"),
        "{msg}"
    );
}
