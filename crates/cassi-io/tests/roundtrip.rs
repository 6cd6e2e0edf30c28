//! Saving then loading gives the same cube/frame; what we write is read
//! correctly by independent readers (ndarray-npy, matfile, SciPy when present);
//! writes are atomic; PNGs hold the intended values.

mod common;

use std::path::Path;

use cassi_core::color::RgbImage;
use cassi_core::{Cube, Frame};
use cassi_io::{
    CubeLayout, IoError, describe, load_array, load_cube, load_frame, save_array, save_cube,
    save_frame, write_band_pngs, write_frame_png16, write_rgb_png,
};
use common::{TempDir, idx3};

/// A cube whose value encodes (band, row, col) as 100 row + 10 col + band.
fn test_cube(bands: usize, rows: usize, cols: usize) -> Cube {
    let mut c = Cube::zeros(bands, rows, cols);
    for b in 0..bands {
        for r in 0..rows {
            for col in 0..cols {
                c.set(b, r, col, idx3(r, col, b));
            }
        }
    }
    c
}

#[test]
fn cube_round_trips_through_every_format() {
    let dir = TempDir::new("cube");
    for (b, r, c) in [(3, 4, 5), (28, 6, 7), (1, 3, 4)] {
        let cube = test_cube(b, r, c);
        for ext in ["npy", "npz", "mat"] {
            let p = dir.join(&format!("c{b}x{r}x{c}.{ext}"));
            save_cube(&p, &cube, "cube").unwrap();
            let back = load_cube(&p, Some("cube"), CubeLayout::Auto).unwrap();
            assert_eq!(back, cube, "{ext} {b}×{r}×{c}");
        }
        // .mat stores the MATLAB convention (rows, cols, bands).
        let a = load_array(dir.join(&format!("c{b}x{r}x{c}.mat")), Some("cube")).unwrap();
        assert_eq!(
            (a.shape.clone(), a.dtype.as_str()),
            (vec![r, c, b], "single")
        );
        assert_eq!(a.data, common::idx3_data(r, c, b));
        // .npy stores (bands, rows, cols).
        let a = load_array(dir.join(&format!("c{b}x{r}x{c}.npy")), None).unwrap();
        assert_eq!(a.shape, vec![b, r, c]);
    }
}

#[test]
fn frame_round_trips_through_every_format() {
    let dir = TempDir::new("frame");
    let mut f = Frame::zeros(5, 7);
    for r in 0..5 {
        for c in 0..7 {
            f.set(r, c, idx3(r, c, 0) / 7.0 - 3.25);
        }
    }
    for ext in ["npy", "npz", "mat"] {
        let p = dir.join(&format!("meas.{ext}"));
        save_frame(&p, &f, "measurement").unwrap();
        assert_eq!(load_frame(&p, Some("measurement")).unwrap(), f, "{ext}");
        assert_eq!(load_frame(&p, None).unwrap(), f, "{ext}");
    }
    let s = describe(dir.join("meas.npz")).unwrap();
    assert_eq!(s.variables[0].name, "measurement");
    assert_eq!(s.variables[0].shape, vec![5, 7]);
}

#[test]
fn written_npy_and_npz_read_with_ndarray_npy() {
    use ndarray::Array3;
    use ndarray_npy::{NpzReader, ReadNpyExt};
    let dir = TempDir::new("oracle-npy");
    let cube = test_cube(3, 4, 5);
    save_cube(dir.join("c.npy"), &cube, "cube").unwrap();
    save_cube(dir.join("c.npz"), &cube, "scene").unwrap();
    let a = Array3::<f32>::read_npy(std::fs::File::open(dir.join("c.npy")).unwrap()).unwrap();
    assert_eq!(a.dim(), (3, 4, 5));
    assert_eq!(a[[2, 3, 4]], cube.get(2, 3, 4));
    assert_eq!(a.iter().copied().collect::<Vec<_>>(), cube.as_slice());
    let mut z = NpzReader::new(std::fs::File::open(dir.join("c.npz")).unwrap()).unwrap();
    assert_eq!(z.names().unwrap(), vec!["scene".to_string()]);
    let b: Array3<f32> = z.by_name("scene").unwrap();
    assert_eq!(b, a);
}

#[test]
fn written_mat_reads_with_the_matfile_crate() {
    let dir = TempDir::new("oracle-mat");
    let cube = test_cube(3, 4, 5);
    let p = dir.join("c.mat");
    save_cube(&p, &cube, "scene_1").unwrap();
    let m = matfile::MatFile::parse(std::fs::File::open(&p).unwrap()).unwrap();
    let arr = m.find_by_name("scene_1").unwrap();
    assert_eq!(arr.size(), &vec![4, 5, 3]);
    let matfile::NumericData::Single { real, imag: None } = arr.data() else {
        panic!("not single: {:?}", arr.data());
    };
    // Column-major (rows, cols, bands): element (r, c, b) at r + 4 (c + 5 b).
    for (r, c, b) in [(0, 0, 0), (3, 4, 2), (1, 2, 1)] {
        assert_eq!(real[r + 4 * (c + 5 * b)], idx3(r, c, b));
    }
}

/// A Python with SciPy, from CASSI_PYTHON, the reference venv, or python3.
fn python_with_scipy() -> Option<String> {
    let candidates = [
        std::env::var("CASSI_PYTHON").ok(),
        Some("/work/pyref/bin/python".to_string()),
        Some("python3".to_string()),
    ];
    candidates.into_iter().flatten().find(|py| {
        std::process::Command::new(py)
            .args(["-c", "import scipy.io"])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

#[test]
fn written_mat_reads_with_scipy_when_available() {
    let Some(py) = python_with_scipy() else {
        eprintln!("note: no Python with SciPy found (set CASSI_PYTHON); skipping the SciPy check");
        return;
    };
    let dir = TempDir::new("scipy");
    let p = dir.join("c.mat");
    save_cube(&p, &test_cube(3, 4, 5), "cube").unwrap();
    let script = common::fixture("make_fixtures.py");
    let out = std::process::Command::new(&py)
        .arg(&script)
        .args(["--check-mat", p.to_str().unwrap(), "cube", "4", "5", "3"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "SciPy could not read our .mat: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn writes_are_atomic_and_leave_no_temporary_files() {
    let dir = TempDir::new("atomic");
    let p = dir.join("out.mat");
    save_cube(&p, &test_cube(3, 4, 5), "cube").unwrap();
    let before = std::fs::read(&p).unwrap();
    // A failing save (invalid MATLAB name) leaves the old file as it was.
    let e = save_cube(&p, &test_cube(2, 2, 2), "2bad name").unwrap_err();
    assert!(matches!(e, IoError::InvalidArgument { .. }), "{e}");
    assert!(e.to_string().contains("not a valid MATLAB variable name"));
    assert_eq!(std::fs::read(&p).unwrap(), before);
    // Overwriting replaces the file completely.
    save_cube(&p, &test_cube(2, 3, 3), "cube").unwrap();
    assert_eq!(
        load_cube(&p, None, CubeLayout::RowsColsBands)
            .unwrap()
            .shape(),
        (2, 3, 3)
    );
    assert_eq!(dir.entries(), vec!["out.mat".to_string()]);
    // A missing directory is a write error naming the output path.
    let q = dir.join("missing/out.npy");
    let e = save_frame(&q, &Frame::zeros(2, 2), "f").unwrap_err();
    assert!(matches!(e, IoError::Write { .. }));
    assert!(e.to_string().contains("missing/out.npy"), "{e}");
    // Shape/data mismatch is refused before anything is written.
    assert!(save_array(dir.join("x.npy"), "x", &[2, 3], &[0.0; 5]).is_err());
    assert_eq!(dir.entries(), vec!["out.mat".to_string()]);
}

fn read_png16(p: &Path) -> (u32, u32, Vec<u16>) {
    let img = image::open(p).unwrap();
    let g = img.as_luma16().expect("a 16-bit grayscale PNG");
    (g.width(), g.height(), g.as_raw().clone())
}

#[test]
fn png16_maps_the_white_level_to_65535() {
    let dir = TempDir::new("png");
    let f = Frame::from_vec(2, 3, vec![0.0, 0.5, 1.0, 2.0, -1.0, f32::NAN]).unwrap();
    let p = dir.join("f.png");
    write_frame_png16(&p, &f, None).unwrap();
    let (w, h, px) = read_png16(&p);
    assert_eq!((w, h), (3, 2));
    // max = 2 → white; negatives and NaN → 0.
    assert_eq!(px, vec![0, 16384, 32768, 65535, 0, 0]);
    write_frame_png16(&p, &f, Some(1.0)).unwrap();
    let (_, _, px) = read_png16(&p);
    assert_eq!(
        px,
        vec![0, 32768, 65535, 65535, 0, 0],
        "clamped above the white level"
    );
    assert!(write_frame_png16(&p, &f, Some(0.0)).is_err());
    assert!(write_frame_png16(dir.join("e.png"), &Frame::zeros(0, 3), None).is_err());
}

#[test]
fn band_pngs_share_one_white_level() {
    let dir = TempDir::new("bands");
    let mut c = Cube::zeros(3, 2, 2);
    c.band_mut(0).copy_from_slice(&[0.0, 1.0, 2.0, 4.0]);
    c.band_mut(2).copy_from_slice(&[1.0, 1.0, 1.0, 1.0]);
    let paths = write_band_pngs(&dir.0, "scene", &c).unwrap();
    let names: Vec<_> = paths
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        ["scene_band00.png", "scene_band01.png", "scene_band02.png"]
    );
    assert_eq!(read_png16(&paths[0]).2, vec![0, 16384, 32768, 65535]);
    assert_eq!(read_png16(&paths[1]).2, vec![0, 0, 0, 0]);
    assert_eq!(read_png16(&paths[2]).2, vec![16384; 4]);
    assert!(write_band_pngs(dir.join("nope"), "scene", &c).is_err());
}

#[test]
fn rgb_png_holds_the_bytes() {
    let dir = TempDir::new("rgb");
    let img = RgbImage {
        rows: 2,
        cols: 2,
        data: vec![255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30],
    };
    let p = dir.join("rgb.png");
    write_rgb_png(&p, &img).unwrap();
    let back = image::open(&p).unwrap();
    let rgb = back.as_rgb8().expect("an 8-bit RGB PNG");
    assert_eq!(rgb.as_raw(), &img.data);
    let bad = RgbImage {
        rows: 2,
        cols: 2,
        data: vec![0; 5],
    };
    assert!(write_rgb_png(dir.join("bad.png"), &bad).is_err());
    // A real pseudo-RGB rendering goes through too.
    let c = test_cube(28, 3, 3);
    let img = cassi_core::color::pseudo_rgb(&c, &cassi_core::STANDARD_WAVELENGTHS_NM).unwrap();
    write_rgb_png(dir.join("pseudo.png"), &img).unwrap();
    assert_eq!(image::open(dir.join("pseudo.png")).unwrap().width(), 3);
}

#[test]
fn describe_text_and_json() {
    let s = describe(common::fixture("v5_types.mat")).unwrap();
    let text = s.to_string();
    assert!(text.contains("MATLAB v5 MAT-file, 12 variables"), "{text}");
    for needle in [
        "cube",
        "4×5×3",
        "double",
        "342",
        "logical",
        "char",
        "complex double",
    ] {
        assert!(text.contains(needle), "{needle}: {text}");
    }
    let cube = s.variables.iter().find(|v| v.name == "cube").unwrap();
    let st = cube.stats.as_ref().unwrap();
    assert_eq!(
        (st.count, st.min, st.max, st.mean),
        (60, Some(0.0), Some(342.0), Some(171.0))
    );
    let json: serde_json::Value = serde_json::to_value(&s).unwrap();
    assert_eq!(json["format"], "mat-v5");
    assert_eq!(json["variables"][7]["name"], "cube");
    assert_eq!(json["variables"][7]["shape"], serde_json::json!([4, 5, 3]));
    assert_eq!(json["variables"][7]["stats"]["max"], 342.0);
    assert_eq!(json["variables"][10]["numeric"], false);
    let npz = serde_json::to_value(describe(common::fixture("arrays.npz")).unwrap()).unwrap();
    assert_eq!(npz["format"], "npz");
}
