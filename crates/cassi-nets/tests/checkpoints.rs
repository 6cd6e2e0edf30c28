//! Checkpoint loading: the official MST-S `.pth` against its `.safetensors`
//! copy (shared data), and hand-made good and bad files written to a temp
//! dir (no shared data needed): strided views, `module.` prefixes, a whole
//! pickled model, truncation, and missing / unexpected / mis-shaped tensors.

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};

use cassi_nets::{DType, HsiSdecnn, Mst, MstConfig, NetError, TensorMap};
use common::torch_pickle::{c_strides, pickle_int, pickle_str};

/// A fresh scratch directory for one test, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let p = std::env::temp_dir().join(format!("cassi-nets-{}-{test}", std::process::id()));
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

/// One tensor to write: name, shape, stride (C order when `None`), values
/// of the whole storage.
struct Spec {
    name: String,
    shape: Vec<usize>,
    stride: Option<Vec<usize>>,
    storage: Vec<f32>,
}

fn spec(name: &str, shape: &[usize]) -> Spec {
    let n: usize = shape.iter().product();
    Spec {
        name: name.into(),
        shape: shape.to_vec(),
        stride: None,
        storage: (0..n).map(|i| (i % 97) as f32 * 0.01 - 0.3).collect(),
    }
}

/// The pickle torch.save writes for an OrderedDict of float tensors (protocol 2).
fn state_dict_pickle(tensors: &[Spec]) -> Vec<u8> {
    let mut p = vec![0x80, 2];
    p.extend(b"ccollections\nOrderedDict\n)R(");
    for (i, t) in tensors.iter().enumerate() {
        pickle_str(&mut p, &t.name);
        p.extend(b"ctorch._utils\n_rebuild_tensor_v2\n(");
        p.push(b'(');
        pickle_str(&mut p, "storage");
        p.extend(b"ctorch\nFloatStorage\n");
        pickle_str(&mut p, &i.to_string());
        pickle_str(&mut p, "cpu");
        pickle_int(&mut p, t.storage.len());
        p.extend(b"tQ");
        pickle_int(&mut p, 0);
        p.push(b'(');
        t.shape.iter().for_each(|&d| pickle_int(&mut p, d));
        p.extend(b"t(");
        let stride = t.stride.clone().unwrap_or_else(|| c_strides(&t.shape));
        stride.iter().for_each(|&d| pickle_int(&mut p, d));
        p.extend(b"t\x89ccollections\nOrderedDict\n)RtR");
    }
    p.extend(b"u.");
    p
}

fn write_zip(path: &Path, entries: &[(String, Vec<u8>)]) {
    let f = std::fs::File::create(path).unwrap();
    let mut z = zip::ZipWriter::new(f);
    let opts =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, bytes) in entries {
        z.start_file(name.as_str(), opts).unwrap();
        z.write_all(bytes).unwrap();
    }
    z.finish().unwrap();
}

/// A torch.save-style zip checkpoint of `tensors`.
fn write_pth(path: &Path, tensors: &[Spec]) {
    let mut entries = vec![("archive/data.pkl".to_string(), state_dict_pickle(tensors))];
    for (i, t) in tensors.iter().enumerate() {
        let bytes = t.storage.iter().flat_map(|v| v.to_le_bytes()).collect();
        entries.push((format!("archive/data/{i}"), bytes));
    }
    entries.push(("archive/version".into(), b"3\n".to_vec()));
    write_zip(path, &entries);
}

fn write_safetensors(path: &Path, tensors: &[Spec]) {
    let mut header = serde_json::Map::new();
    let mut data = Vec::new();
    for t in tensors {
        let begin = data.len();
        data.extend(t.storage.iter().flat_map(|v| v.to_le_bytes()));
        header.insert(
            t.name.clone(),
            serde_json::json!({"dtype": "F32", "shape": t.shape, "data_offsets": [begin, data.len()]}),
        );
    }
    let h = serde_json::to_vec(&serde_json::Value::Object(header)).unwrap();
    let mut bytes = (h.len() as u64).to_le_bytes().to_vec();
    bytes.extend(h);
    bytes.extend(data);
    std::fs::write(path, bytes).unwrap();
}

/// The 30 tensors of HSI_SDeCNN(7, 1, 128, 15), as a hand-made state dict.
fn hsi_sdecnn_specs() -> Vec<Spec> {
    let mut v = Vec::new();
    for i in 0..15 {
        let cin = if i == 0 { 29 } else { 128 };
        let cout = if i == 14 { 4 } else { 128 };
        v.push(spec(&format!("model.{}.weight", 2 * i), &[cout, cin, 3, 3]));
        v.push(spec(&format!("model.{}.bias", 2 * i), &[cout]));
    }
    v
}

fn load_err(path: &Path) -> String {
    match TensorMap::load(path) {
        Ok(m) => panic!(
            "{} loaded {} tensors, expected an error",
            path.display(),
            m.len()
        ),
        Err(e) => e.to_string(),
    }
}

#[test]
fn official_mst_s_pth_holds_the_same_tensors_as_its_safetensors_copy() {
    let Some(data) = cassi_io::shared_data::for_test(&[]) else {
        return;
    };
    let pth = TensorMap::load(data.join("weights/mst_s.pth")).unwrap_or_else(|e| panic!("{e}"));
    let st = TensorMap::load(data.join("nets/mst_s/mst_s.safetensors"))
        .unwrap_or_else(|e| panic!("{e}"));
    for m in [&pth, &st] {
        assert_eq!(m.len(), 202, "{}", m.path().display());
        assert_eq!(m.parameter_count(), 922_648, "{}", m.path().display());
    }
    for (name, t) in pth.iter() {
        let other = st
            .get(name)
            .unwrap_or_else(|| panic!("{name} missing from the safetensors"));
        assert_eq!(t.dtype, DType::F32);
        assert_eq!(t.tensor, other.tensor, "{name} differs");
    }
    // And it loads strictly into MST-S.
    Mst::from_tensors(pth, MstConfig::SMALL).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn hand_made_pth_and_safetensors_load_alike_with_strides_and_prefix() {
    let dir = TempDir::new("good");
    // A 2×3 tensor stored column-major (stride (1, 2)), as a transposed view is saved.
    let strided = Spec {
        name: "module.t".into(),
        shape: vec![2, 3],
        stride: Some(vec![1, 2]),
        storage: vec![0.0, 3.0, 1.0, 4.0, 2.0, 5.0],
    };
    let plain = Spec {
        name: "module.b".into(),
        ..spec("", &[4])
    };
    write_pth(&dir.file("a.pth"), &[strided, plain]);
    let m = TensorMap::load(dir.file("a.pth")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        m.names().collect::<Vec<_>>(),
        ["b", "t"],
        "module. prefix stripped"
    );
    assert_eq!(
        m.get("t").unwrap().tensor.data(),
        [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    );
    assert_eq!(m.get("t").unwrap().tensor.shape(), [2, 3]);

    // The same network weights load from either format.
    write_pth(&dir.file("h.pth"), &hsi_sdecnn_specs());
    write_safetensors(&dir.file("h.safetensors"), &hsi_sdecnn_specs());
    let a = TensorMap::load(dir.file("h.pth")).unwrap();
    let b = TensorMap::load(dir.file("h.safetensors")).unwrap();
    assert_eq!(a.len(), 30);
    assert_eq!(a.parameter_count(), 1_956_740);
    for (name, t) in a.iter() {
        assert_eq!(t.tensor, b.get(name).unwrap().tensor, "{name}");
    }
    HsiSdecnn::from_tensors(a).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn missing_unexpected_and_misshaped_tensors_are_listed_in_one_error() {
    let dir = TempDir::new("mismatch");
    let mut specs = hsi_sdecnn_specs();
    specs.retain(|s| s.name != "model.0.weight"); // missing
    specs.push(spec("model.30.weight", &[4, 128, 3, 3])); // unexpected
    let bad = specs
        .iter_mut()
        .find(|s| s.name == "model.2.weight")
        .unwrap();
    *bad = spec("model.2.weight", &[128, 128, 3, 1]); // wrong shape
    for file in ["bad.pth", "bad.safetensors"] {
        let path = dir.file(file);
        if file.ends_with("pth") {
            write_pth(&path, &specs);
        } else {
            write_safetensors(&path, &specs);
        }
        let err = match HsiSdecnn::load(&path) {
            Ok(_) => panic!("{file}: loaded despite bad tensors"),
            Err(e) => e,
        };
        assert!(matches!(err, NetError::WeightMismatch { .. }), "{err:?}");
        let msg = err.to_string();
        eprintln!("{msg}");
        for needle in [
            file,
            "HSI-SDeCNN",
            "missing: model.0.weight [128, 29, 3, 3]",
            "unexpected: model.30.weight [4, 128, 3, 3]",
            "wrong shape: model.2.weight: got [128, 128, 3, 1], wanted [128, 128, 3, 3]",
        ] {
            assert!(msg.contains(needle), "{file}: no {needle:?} in:\n{msg}");
        }
    }
}

#[test]
fn a_whole_pickled_model_is_refused_not_read_as_empty() {
    let dir = TempDir::new("whole");
    // torch.save(model): the top object is an instance of the model class.
    let pkl = b"\x80\x02carchitecture.MST\nMST\nq\x00)\x81}(X\x08\x00\x00\x00trainingq\x01\x88ub."
        .to_vec();
    write_zip(
        &dir.file("model.pth"),
        &[
            ("archive/data.pkl".into(), pkl),
            ("archive/version".into(), b"3\n".to_vec()),
        ],
    );
    let msg = load_err(&dir.file("model.pth"));
    assert!(msg.contains("model.pth"), "{msg}");
    assert!(
        msg.contains("whole pickled object of class architecture.MST.MST"),
        "{msg}"
    );
    assert!(msg.contains("state_dict"), "{msg}");
}

#[test]
fn truncated_and_foreign_files_give_clear_errors() {
    let dir = TempDir::new("truncated");
    let specs = vec![spec("w", &[8, 4]), spec("b", &[8])];
    write_pth(&dir.file("ok.pth"), &specs);
    write_safetensors(&dir.file("ok.safetensors"), &specs);
    for (name, cut) in [
        ("ok.pth", 0.6),
        ("ok.pth", 0.1),
        ("ok.safetensors", 0.9),
        ("ok.safetensors", 0.02),
    ] {
        let bytes = std::fs::read(dir.file(name)).unwrap();
        let short = dir.file(&format!("short-{cut}-{name}"));
        std::fs::write(&short, &bytes[..(bytes.len() as f64 * cut) as usize]).unwrap();
        let msg = load_err(&short);
        assert!(msg.contains(&short.display().to_string()), "{msg}");
        assert!(
            msg.contains("truncated") || msg.contains("not a readable PyTorch zip"),
            "{name} cut to {cut}: {msg}"
        );
    }
    std::fs::write(dir.file("empty.bin"), b"").unwrap();
    assert!(
        load_err(&dir.file("empty.bin"))
            .contains("neither a PyTorch zip checkpoint nor a safetensors file")
    );
    std::fs::write(
        dir.file("text.txt"),
        b"hello, this is not a checkpoint at all",
    )
    .unwrap();
    assert!(load_err(&dir.file("text.txt")).contains("neither"));
    let missing = load_err(&dir.file("does-not-exist.pth"));
    assert!(
        missing.contains("does-not-exist.pth") && missing.contains("cannot read"),
        "{missing}"
    );
}

#[test]
fn views_larger_than_their_storage_or_absurdly_large_are_refused() {
    let dir = TempDir::new("views");
    // A stride-0 view claiming 2^40 elements of a 1-element storage.
    let huge = Spec {
        name: "w".into(),
        shape: vec![1 << 20, 1 << 20],
        stride: Some(vec![0, 0]),
        storage: vec![1.0],
    };
    write_pth(&dir.file("huge.pth"), &[huge]);
    let msg = load_err(&dir.file("huge.pth"));
    assert!(
        msg.contains("tensor w") && msg.contains("too large"),
        "{msg}"
    );
    // A view reaching past the end of its storage.
    let past = Spec {
        name: "v".into(),
        shape: vec![3, 3],
        stride: Some(vec![3, 1]),
        storage: vec![0.0; 8],
    };
    write_pth(&dir.file("past.pth"), &[past]);
    let msg = load_err(&dir.file("past.pth"));
    assert!(
        msg.contains("tensor v") && msg.contains("reaches element 8"),
        "{msg}"
    );
}
