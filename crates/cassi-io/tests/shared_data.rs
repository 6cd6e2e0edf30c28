//! Loads every public benchmark file of `../shared/data` (masks, real
//! measurements, CAVE scenes) when that directory exists. It is not part of
//! the repository: without it this test prints a note and passes (fails
//! under `CASSI_REQUIRE_SHARED_DATA=1`; see `cassi_io::shared_data`).

use std::path::PathBuf;

use cassi_io::{CubeLayout, describe, load_cube, load_frame, shared_data};

fn files(dir: PathBuf, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == ext))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn loads_all_shared_benchmark_files() {
    let Some(data) = shared_data::for_test(&["masks", "real", "scenes"]) else {
        return;
    };
    let mut loaded = 0;
    for p in files(data.join("masks"), "mat")
        .into_iter()
        .chain(files(data.join("real"), "mat"))
    {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        let var = if name.starts_with("scene") {
            "meas_real"
        } else {
            "mask"
        };
        let f = load_frame(&p, Some(var)).unwrap_or_else(|e| panic!("{e}"));
        // The only numeric variable: loading without a name gives the same frame.
        assert_eq!(load_frame(&p, None).unwrap(), f, "{name}");
        let want: &[(usize, usize)] = match var {
            "meas_real" => &[(660, 714)],
            _ => &[(256, 256), (512, 512), (660, 660)],
        };
        assert!(want.contains(&f.shape()), "{name}: shape {:?}", f.shape());
        let (lo, hi) = f
            .as_slice()
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        assert!(
            lo >= 0.0 && hi <= 1.0 && hi > 0.5,
            "{name}: range {lo}…{hi}"
        );
        let mean = f.as_slice().iter().map(|&v| v as f64).sum::<f64>() / f.as_slice().len() as f64;
        assert!(mean > 0.01, "{name}: mean {mean}");
        // Binary masks are binary.
        if name.starts_with("binary") {
            assert!(f.as_slice().iter().all(|&v| v == 0.0 || v == 1.0), "{name}");
        }
        // A MATLAB mask is not symmetric: a transposed read would differ.
        if var == "mask" {
            let n = f.rows();
            let asym = (0..n).any(|r| (0..n).any(|c| f.get(r, c) != f.get(c, r)));
            assert!(asym, "{name}: symmetric?");
        }
        loaded += 1;
    }
    // The TSA simulation mask's documented range (MANIFEST.md): 0.0066…1, mean 0.56.
    let tsa = data.join("masks/tsa_simu_mask256.mat");
    if tsa.exists() {
        let s = describe(&tsa).unwrap();
        let st = s.variables[0].stats.clone().unwrap();
        assert!((st.min.unwrap() - 0.0066).abs() < 1e-3, "{st:?}");
        assert!((st.mean.unwrap() - 0.56).abs() < 0.01, "{st:?}");
    }
    for p in files(data.join("scenes"), "npy") {
        let c = load_cube(&p, None, CubeLayout::Auto).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(c.shape(), (28, 256, 256), "{}", p.display());
        let (lo, hi) = c
            .as_slice()
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        assert!(
            lo >= 0.0 && (hi - 1.0).abs() < 1e-6,
            "{}: {lo}…{hi}",
            p.display()
        );
        loaded += 1;
    }
    eprintln!("loaded {loaded} shared data files from {}", data.display());
    assert!(
        loaded >= 19,
        "expected the 9 .mat and 10 .npy files, found {loaded}"
    );
}
