//! Every failure is an error naming the file and saying what is wrong; no
//! malformed input makes a reader panic or return damaged data.

mod common;

use cassi_core::Cube;
use cassi_io::{CubeLayout, IoError, describe, load_array, load_cube, load_frame, save_cube};
use common::{TempDir, assert_err, fixture};

#[test]
fn missing_file() {
    for name in ["nope.mat", "nope.npy", "nope.npz"] {
        let p = fixture(name);
        let e = assert_err(load_frame(&p, None), &p, &["no such file"]);
        assert!(matches!(e, IoError::NotFound { .. }), "{e:?}");
        assert!(matches!(describe(&p), Err(IoError::NotFound { .. })));
    }
}

#[test]
fn truncated_files() {
    for (name, needles) in [
        (
            "truncated.npy",
            &["truncated NumPy .npy", "needs 240 bytes", "203"][..],
        ),
        (
            "truncated_v5.mat",
            &["truncated MATLAB v5", "announces"][..],
        ),
        (
            "truncated_v5_compressed.mat",
            &["truncated MATLAB v5", "announces"][..],
        ),
        (
            "truncated_v73.mat",
            &["truncated MATLAB v7.3", "end of data"][..],
        ),
    ] {
        let p = fixture(name);
        let e = assert_err(describe(&p), &p, needles);
        assert!(matches!(e, IoError::Truncated { .. }), "{name}: {e:?}");
        assert!(load_array(&p, Some("d")).is_err());
    }
}

#[test]
fn garbage_files() {
    for (name, needle) in [
        ("garbage.mat", "no MATLAB v5 header and no HDF5 signature"),
        ("garbage.npy", "NumPy magic"),
        ("garbage.npz", "not a valid NumPy .npz file"),
    ] {
        let p = fixture(name);
        let e = assert_err(load_frame(&p, None), &p, &["not a valid", needle]);
        assert!(matches!(e, IoError::Corrupt { .. }), "{e:?}");
    }
}

#[test]
fn unknown_variable_lists_the_present_ones() {
    let p = fixture("v5_types.mat");
    let e = assert_err(
        load_frame(&p, Some("meas")),
        &p,
        &[
            "no variable named 'meas'",
            "'d' 2×3 double",
            "'u8' 2×3 uint8",
            "'lg' 2×3 logical",
            "'cube' 4×5×3 double",
            "'txt' 1×5 char",
        ],
    );
    assert!(matches!(e, IoError::VariableNotFound { .. }));
    let p = fixture("v73.mat");
    assert_err(
        load_cube(&p, Some("scene"), CubeLayout::Auto),
        &p,
        &["'scene'", "'cube' 4×5×3 double", "'mask' 4×6 single"],
    );
    let p = fixture("arrays.npz");
    assert_err(
        load_frame(&p, Some("meas")),
        &p,
        &["'meas'", "'cube' 3×4×5 float32", "'mask' 4×5 float64"],
    );
}

#[test]
fn wrong_dimensions_name_got_and_wanted() {
    let p = fixture("v5_types.mat");
    let e = assert_err(
        load_cube(&p, Some("d"), CubeLayout::Auto),
        &p,
        &["variable 'd'", "shape 2×3", "expected a 3-D cube"],
    );
    assert!(matches!(e, IoError::Shape { .. }));
    assert_err(
        load_frame(&p, Some("cube")),
        &p,
        &["variable 'cube'", "shape 4×5×3", "expected a 2-D frame"],
    );
    let p = fixture("vector.npy");
    assert_err(
        load_frame(&p, None),
        &p,
        &["shape 6 (1-D)", "expected a 2-D frame"],
    );
}

#[test]
fn non_finite_values_are_located() {
    let p = fixture("frame_nan.npy");
    let e = assert_err(
        load_frame(&p, None),
        &p,
        &[
            "variable 'frame_nan'",
            "non-finite value (NaN)",
            "index [1, 2]",
        ],
    );
    assert!(matches!(e, IoError::NonFinite { .. }));
    let p = fixture("v5_nan.mat");
    assert_err(
        load_frame(&p, Some("meas")),
        &p,
        &["'meas'", "NaN", "[1, 2]"],
    );
    let p = fixture("cube_inf.npy");
    assert_err(
        load_cube(&p, None, CubeLayout::Auto),
        &p,
        &["(-inf)", "index [1, 2, 3]"],
    );
    // describe reports them instead of failing.
    let s = describe(fixture("v5_nan.mat")).unwrap();
    assert_eq!(s.variables[0].stats.as_ref().unwrap().non_finite, 1);
}

#[test]
fn unknown_extension() {
    let dir = TempDir::new("ext");
    let p = dir.join("scene.txt");
    std::fs::write(&p, b"hello").unwrap();
    assert_err(
        load_frame(&p, None),
        &p,
        &["unknown file format", "'.txt'", ".mat, .npy, .npz"],
    );
    let q = dir.join("cube.tiff");
    let e = assert_err(
        save_cube(&q, &Cube::zeros(2, 2, 2), "cube"),
        &q,
        &["'.tiff'", "by extension"],
    );
    assert!(matches!(e, IoError::UnknownFormat { .. }));
    let r = dir.join("noext");
    assert_err(describe(&r), &r, &["no extension"]);
    assert_eq!(
        dir.entries(),
        vec!["scene.txt".to_string()],
        "nothing written"
    );
}

#[test]
fn unsupported_element_types() {
    let p = fixture("v5_types.mat");
    let e = assert_err(
        load_frame(&p, Some("z")),
        &p,
        &["variable 'z'", "complex double", "real(x)"],
    );
    assert!(matches!(e, IoError::UnsupportedType { .. }));
    assert_err(load_frame(&p, Some("txt")), &p, &["'txt'", "char"]);
    assert_err(load_frame(&p, Some("st")), &p, &["'st'", "struct"]);
}

/// Deterministic xorshift for the fuzz test.
fn next(s: &mut u64) -> u64 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    *s
}

/// Cutting or corrupting a file never panics, and never yields values that
/// differ from the intact file: either an error, or a prefix of the same
/// variables with the same statistics.
#[test]
fn damaged_files_never_panic_or_return_wrong_data() {
    let dir = TempDir::new("fuzz");
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for name in [
        "v5_types.mat",
        "v5_types_compressed.mat",
        "v73.mat",
        "cube_f32_f.npy",
        "arrays.npz",
        "arrays_compressed.npz",
    ] {
        let full = std::fs::read(fixture(name)).unwrap();
        let good = describe(fixture(name)).unwrap().variables;
        let ext = name.rsplit('.').next().unwrap();
        let target = dir.join(&format!("damaged.{ext}"));
        let mut cases: Vec<Vec<u8>> = Vec::new();
        for cut in (0..full.len()).step_by(13) {
            cases.push(full[..cut].to_vec());
        }
        for _ in 0..300 {
            let mut b = full.clone();
            for _ in 0..1 + next(&mut seed) % 4 {
                let i = (next(&mut seed) as usize) % b.len();
                b[i] = next(&mut seed) as u8;
            }
            cases.push(b);
        }
        for (n, bytes) in cases.iter().enumerate() {
            std::fs::write(&target, bytes).unwrap();
            let truncation = n < full.len().div_ceil(13);
            match describe(&target) {
                Err(e) => assert!(e.to_string().contains("damaged"), "{e}"),
                Ok(s) if truncation && !name.ends_with("v73.mat") => {
                    assert!(s.variables.len() <= good.len(), "{name} case {n}");
                    for (got, want) in s.variables.iter().zip(&good) {
                        assert_eq!(
                            got,
                            want,
                            "{name}: cut at {} returned altered data",
                            bytes.len()
                        );
                    }
                }
                Ok(_) => {}
            }
            let _ = load_array(&target, Some("cube"));
        }
    }
}
