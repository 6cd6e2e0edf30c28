//! Reading every supported format and element type, with axis order pinned
//! by fixtures whose values encode their index (100 i + 10 j + k).

mod common;

use cassi_io::{CubeLayout, FileFormat, IoError, describe, load_array, load_cube, load_frame};
use common::{fixture, idx3, idx3_data};

/// (name, MATLAB class, shape, C-order values) of the small 2-D variables of
/// `v5_types.mat` (see make_fixtures.py).
fn v5_small_vars() -> Vec<(&'static str, &'static str, Vec<usize>, Vec<f32>)> {
    vec![
        (
            "d",
            "double",
            vec![2, 3],
            vec![1.0, 2.0, 3.0, 4.0, 5.5, 6.0],
        ),
        (
            "s",
            "single",
            vec![2, 3],
            vec![0.5, 1.0, 1.5, 2.0, 2.5, -3.0],
        ),
        (
            "u8",
            "uint8",
            vec![2, 3],
            vec![0.0, 1.0, 2.0, 200.0, 254.0, 255.0],
        ),
        (
            "u16",
            "uint16",
            vec![2, 3],
            vec![0.0, 1.0, 2.0, 1000.0, 40000.0, 65535.0],
        ),
        (
            "lg",
            "logical",
            vec![2, 3],
            vec![1.0, 0.0, 1.0, 0.0, 1.0, 0.0],
        ),
        ("i16", "int16", vec![2, 2], vec![-300.0, 2.0, 7.0, 32767.0]),
        (
            "i32",
            "int32",
            vec![2, 2],
            vec![-70000.0, 2.0, 7.0, 123456.0],
        ),
    ]
}

#[test]
fn mat_v5_every_class_uncompressed_and_compressed() {
    for file in ["v5_types.mat", "v5_types_compressed.mat"] {
        let path = fixture(file);
        for (name, class, shape, values) in v5_small_vars() {
            let a = load_array(&path, Some(name)).unwrap();
            assert_eq!(a.name, name);
            assert_eq!(a.dtype, class, "{file}:{name}");
            assert_eq!(a.shape, shape, "{file}:{name}");
            assert_eq!(a.data, values, "{file}:{name}");
        }
        // 3-D double: MATLAB size (4, 5, 3), C order of that size.
        let a = load_array(&path, Some("cube")).unwrap();
        assert_eq!(a.shape, vec![4, 5, 3]);
        assert_eq!(
            a.data,
            idx3_data(4, 5, 3),
            "{file}: axis order of a 3-D array"
        );
        let b = load_array(&path, Some("cube_brc")).unwrap();
        assert_eq!(
            (b.dtype.as_str(), b.shape.clone()),
            ("single", vec![3, 8, 9])
        );
        assert_eq!(b.data, idx3_data(3, 8, 9));
        let s = describe(&path).unwrap();
        assert_eq!(s.format, FileFormat::MatV5);
    }
}

#[test]
fn mat_v5_agrees_with_the_matfile_crate() {
    // An independent parser as oracle (it cannot read int32/char/struct, hence
    // the reduced fixtures).
    for file in ["v5_plain.mat", "v5_plain_compressed.mat"] {
        let path = fixture(file);
        let m = matfile::MatFile::parse(std::fs::File::open(&path).unwrap()).unwrap();
        assert_eq!(m.arrays().len(), 8);
        for arr in m.arrays() {
            let colmajor: Vec<f64> = match arr.data() {
                matfile::NumericData::Double { real, .. } => real.clone(),
                matfile::NumericData::Single { real, .. } => {
                    real.iter().map(|&v| v as f64).collect()
                }
                matfile::NumericData::UInt8 { real, .. } => {
                    real.iter().map(|&v| v as f64).collect()
                }
                matfile::NumericData::UInt16 { real, .. } => {
                    real.iter().map(|&v| v as f64).collect()
                }
                matfile::NumericData::Int16 { real, .. } => {
                    real.iter().map(|&v| v as f64).collect()
                }
                other => panic!("unexpected class {other:?}"),
            };
            let ours = load_array(&path, Some(arr.name())).unwrap();
            assert_eq!(&ours.shape, arr.size(), "{file}:{}", arr.name());
            // Element (i0, i1, …) sits at i0 + d0 (i1 + d1 (…)) column-major.
            let shape = arr.size();
            for (flat, &v) in ours.data.iter().enumerate() {
                let mut rem = flat;
                let mut idx = vec![0; shape.len()];
                for d in (0..shape.len()).rev() {
                    idx[d] = rem % shape[d];
                    rem /= shape[d];
                }
                let mut off = 0;
                for d in (0..shape.len()).rev() {
                    off = off * shape[d] + idx[d];
                }
                assert_eq!(v as f64, colmajor[off], "{file}:{} at {idx:?}", arr.name());
            }
        }
    }
}

#[test]
fn mat_cubes_follow_the_auto_layout_rule() {
    for file in ["v5_types.mat", "v5_types_compressed.mat", "v73.mat"] {
        let path = fixture(file);
        // (rows, cols, bands) = (4, 5, 3): the MATLAB default.
        let c = load_cube(&path, Some("cube"), CubeLayout::Auto).unwrap();
        assert_eq!(c.shape(), (3, 4, 5), "{file}");
        for (b, r, col) in [(0, 0, 0), (2, 3, 4), (1, 2, 0), (0, 1, 3)] {
            assert_eq!(c.get(b, r, col), idx3(r, col, b), "{file} ({b},{r},{col})");
        }
        let explicit = load_cube(&path, Some("cube"), CubeLayout::RowsColsBands).unwrap();
        assert_eq!(explicit, c);
        // Forcing the other layout reads the stored axes as (bands, rows, cols).
        let forced = load_cube(&path, Some("cube"), CubeLayout::BandsRowsCols).unwrap();
        assert_eq!(forced.shape(), (4, 5, 3));
        assert_eq!(forced.get(3, 4, 2), idx3(3, 4, 2));
    }
    // (3, 8, 9): the first axis is clearly spectral, the last is not.
    let c = load_cube(fixture("v5_types.mat"), Some("cube_brc"), CubeLayout::Auto).unwrap();
    assert_eq!(c.shape(), (3, 8, 9));
    assert_eq!(c.get(2, 7, 8), idx3(2, 7, 8));
    assert_eq!(c.get(1, 0, 5), idx3(1, 0, 5));
}

#[test]
fn mat_v73_reads_like_v5() {
    let path = fixture("v73.mat");
    let s = describe(&path).unwrap();
    assert_eq!(s.format, FileFormat::MatV73);
    let cube = load_array(&path, Some("cube")).unwrap();
    assert_eq!(
        (cube.dtype.as_str(), cube.shape.clone()),
        ("double", vec![4, 5, 3])
    );
    assert_eq!(cube.data, idx3_data(4, 5, 3));
    let v5 = load_array(fixture("v5_types.mat"), Some("cube")).unwrap();
    assert_eq!(cube.data, v5.data);

    let mask = load_frame(&path, Some("mask")).unwrap();
    assert_eq!(mask.shape(), (4, 6));
    assert_eq!(mask.get(3, 5), (idx3(3, 5, 0) as f64 / 1000.0) as f32);
    let lg = load_array(&path, Some("lg")).unwrap();
    assert_eq!(
        (lg.dtype.as_str(), lg.data.clone()),
        ("logical", vec![1., 0., 1., 0., 1., 0.])
    );
    let u16 = load_array(&path, Some("u16")).unwrap();
    assert_eq!(u16.data, vec![0.0, 1.0, 2.0, 1000.0, 40000.0, 65535.0]);
    // char and struct are listed but not numeric.
    let txt = s.variables.iter().find(|v| v.name == "txt").unwrap();
    assert_eq!(
        (txt.dtype.as_str(), txt.numeric, txt.shape.clone()),
        ("char", false, vec![1, 5])
    );
    assert!(
        s.variables
            .iter()
            .any(|v| v.name == "st" && v.dtype == "struct")
    );
    assert!(matches!(
        load_array(&path, Some("txt")),
        Err(IoError::UnsupportedType { .. })
    ));
}

#[test]
fn variable_choice_by_name_or_the_only_numeric_one() {
    // One numeric variable (plus a char one): no name needed.
    let f = load_frame(fixture("v5_one_numeric.mat"), None).unwrap();
    assert_eq!(f.shape(), (4, 6));
    assert_eq!(f.get(2, 3), (230.0f64 / 1000.0) as f32);
    // A .npz with one array and a .npy need no name either.
    let m = load_frame(fixture("single.npz"), None).unwrap();
    assert_eq!(m.get(3, 4), idx3(3, 4, 0));
    let c = load_cube(fixture("cube_f32_c.npy"), None, CubeLayout::Auto).unwrap();
    assert_eq!(c.shape(), (3, 4, 5));
    // Several numeric variables and no name: an error listing them.
    let p = fixture("v5_types.mat");
    common::assert_err(
        load_array(&p, None),
        &p,
        &[
            "9 numeric variables",
            "'d' 2×3 double",
            "'cube' 4×5×3 double",
            "choose one by name",
        ],
    );
}

#[test]
fn npy_c_fortran_f64_and_big_endian_agree() {
    let want = idx3_data(3, 4, 5);
    for file in [
        "cube_f32_c.npy",
        "cube_f32_f.npy",
        "cube_f64_c.npy",
        "cube_f64_f.npy",
        "cube_f32_be.npy",
    ] {
        let a = load_array(fixture(file), None).unwrap();
        assert_eq!(a.shape, vec![3, 4, 5], "{file}");
        assert_eq!(a.data, want, "{file}");
        let c = load_cube(fixture(file), None, CubeLayout::Auto).unwrap();
        assert_eq!(c.shape(), (3, 4, 5), "{file}");
        assert_eq!(c.get(2, 1, 4), idx3(2, 1, 4), "{file}");
    }
    assert_eq!(
        load_array(fixture("cube_f64_f.npy"), None).unwrap().dtype,
        "float64"
    );
    assert_eq!(
        load_array(fixture("cube_f32_be.npy"), None).unwrap().dtype,
        "float32"
    );
}

#[test]
fn npy_integer_and_bool_types_convert_to_f32() {
    let u8 = load_frame(fixture("frame_u8.npy"), None).unwrap();
    let u16 = load_frame(fixture("frame_u16.npy"), None).unwrap();
    let b = load_frame(fixture("frame_bool.npy"), None).unwrap();
    for r in 0..4 {
        for c in 0..5 {
            let v = 100 * r + 10 * c;
            assert_eq!(u8.get(r, c), (v % 256) as f32);
            assert_eq!(u16.get(r, c), (v * 100) as f32);
            assert_eq!(b.get(r, c), if v % 3 == 0 { 1.0 } else { 0.0 });
        }
    }
    assert_eq!(
        load_array(fixture("frame_bool.npy"), None).unwrap().dtype,
        "bool"
    );
    assert_eq!(
        load_array(fixture("frame_u16.npy"), None).unwrap().dtype,
        "uint16"
    );
}

#[test]
fn npy_with_a_spectral_last_axis_is_read_as_rows_cols_bands() {
    // Stored (8, 9, 3) = (rows, cols, bands), value 100 r + 10 c + b.
    let c = load_cube(fixture("cube_rcb_f32.npy"), None, CubeLayout::Auto).unwrap();
    assert_eq!(c.shape(), (3, 8, 9));
    for (b, r, col) in [(0, 0, 0), (2, 7, 8), (1, 3, 5)] {
        assert_eq!(c.get(b, r, col), idx3(r, col, b));
    }
}

#[test]
fn frames_accept_a_singleton_axis() {
    let f = load_frame(fixture("frame_1xhxw.npy"), None).unwrap();
    assert_eq!(f.shape(), (4, 5));
    assert_eq!(f.get(3, 2), idx3(3, 2, 0));
}

#[test]
fn npz_stored_and_deflated_by_name() {
    for file in ["arrays.npz", "arrays_compressed.npz"] {
        let p = fixture(file);
        let c = load_cube(&p, Some("cube"), CubeLayout::Auto).unwrap();
        assert_eq!(c.shape(), (3, 4, 5));
        assert_eq!(c.as_slice(), &idx3_data(3, 4, 5)[..]);
        let m = load_frame(&p, Some("mask")).unwrap();
        assert_eq!(m.get(2, 4), idx3(2, 4, 0));
        assert_eq!(load_array(&p, Some("mask")).unwrap().dtype, "float64");
        // (3, 8, 3): both end axes could be the bands.
        let e = common::assert_err(
            load_cube(&p, Some("amb"), CubeLayout::Auto),
            &p,
            &["'amb'", "3×8×3", "--layout brc", "--layout rcb"],
        );
        assert!(matches!(e, IoError::AmbiguousLayout { .. }));
        let amb = load_cube(&p, Some("amb"), CubeLayout::RowsColsBands).unwrap();
        assert_eq!(amb.shape(), (3, 3, 8));
        assert_eq!(amb.get(2, 1, 7), idx3(1, 7, 2));
        assert_eq!(describe(&p).unwrap().format, FileFormat::Npz);
    }
}
