//! PyTorch zip checkpoints (`torch.save` since 1.6): `<root>/data.pkl` holds
//! the pickled state dict, `<root>/data/<key>` the raw bytes of each storage.

use std::collections::HashMap;
use std::io::{Cursor, Read};

use super::StoredTensor;
use super::dtype::DType;
use super::pickle::{TensorRef, Value, unpickle};
use crate::tensor::Tensor;

/// Keys under which training scripts commonly nest the state dict.
const NESTED_STATE_DICT_KEYS: [&str; 4] = ["state_dict", "model_state_dict", "model", "net"];

pub(crate) fn read(bytes: &[u8]) -> Result<Vec<(String, StoredTensor)>, String> {
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes))
        .map_err(|e| format!("not a readable PyTorch zip checkpoint: {e}"))?;
    let pkl_name = zip
        .file_names()
        .find(|n| *n == "data.pkl" || n.ends_with("/data.pkl"))
        .map(str::to_string)
        .ok_or("a zip archive without data.pkl: not a PyTorch checkpoint")?;
    let root = &pkl_name[..pkl_name.len() - "data.pkl".len()];
    if let Ok(mut f) = zip.by_name(&format!("{root}byteorder")) {
        let mut order = String::new();
        f.read_to_string(&mut order).ok();
        if order.trim() != "little" {
            return Err(format!(
                "byte order {:?} is not supported (only little)",
                order.trim()
            ));
        }
    }
    let pkl = read_entry(&mut zip, &pkl_name)?;
    let top = unpickle(&pkl)?;
    let entries = state_dict_entries(top)?;

    let mut storages: HashMap<String, Vec<u8>> = HashMap::new();
    let mut out = Vec::with_capacity(entries.len());
    for (name, t) in entries {
        if !storages.contains_key(&t.storage_key) {
            let bytes = read_entry(&mut zip, &format!("{root}data/{}", t.storage_key))
                .map_err(|e| format!("tensor {name}: {e}"))?;
            storages.insert(t.storage_key.clone(), bytes);
        }
        let tensor =
            gather(&t, &storages[&t.storage_key]).map_err(|e| format!("tensor {name}: {e}"))?;
        out.push((name, tensor));
    }
    Ok(out)
}

fn read_entry(zip: &mut zip::ZipArchive<Cursor<&[u8]>>, name: &str) -> Result<Vec<u8>, String> {
    let archive_len = zip.clone().into_inner().into_inner().len() as u64;
    let mut f = zip
        .by_name(name)
        .map_err(|e| format!("zip entry {name}: {e}"))?;
    // The declared size can lie; the archive's own length bounds a stored entry.
    let mut buf = Vec::with_capacity(f.size().min(archive_len) as usize);
    f.read_to_end(&mut buf)
        .map_err(|e| format!("zip entry {name} is unreadable (truncated file?): {e}"))?;
    Ok(buf)
}

/// The (name, tensor) items of the pickled top-level object, which must be
/// a state dict (or hold one under a usual key).
fn state_dict_entries(top: Value) -> Result<Vec<(String, TensorRef)>, String> {
    let items = match top {
        Value::Dict(items) => items,
        Value::Object(class) => {
            return Err(format!(
                "holds a whole pickled object of class {class}, not a state dict; \
                 save it with torch.save(model.state_dict(), path)"
            ));
        }
        other => return Err(format!("holds {}, not a state dict", describe(&other))),
    };
    if !items.iter().any(|(_, v)| matches!(v, Value::Tensor(_))) {
        // A training checkpoint {"epoch": …, "state_dict": {…}}?
        for key in NESTED_STATE_DICT_KEYS {
            if let Some((_, v @ Value::Dict(_))) =
                items.iter().find(|(k, _)| *k == Value::Str(key.into()))
            {
                return state_dict_entries(v.clone())
                    .map_err(|e| format!("under key {key:?}: {e}"));
            }
        }
    }
    let mut out = Vec::with_capacity(items.len());
    let mut non_tensors = Vec::new();
    for (k, v) in items {
        match (k, v) {
            (Value::Str(name), Value::Tensor(t)) => out.push((name, t)),
            (k, v) => non_tensors.push(format!("{} = {}", describe(&k), describe(&v))),
        }
    }
    if !non_tensors.is_empty() {
        let shown: Vec<_> = non_tensors.iter().take(5).cloned().collect();
        return Err(format!(
            "not a state dict: {} entries are not tensors (e.g. {})",
            non_tensors.len(),
            shown.join("; ")
        ));
    }
    if out.is_empty() {
        return Err("the state dict is empty".into());
    }
    Ok(out)
}

fn describe(v: &Value) -> String {
    match v {
        Value::Str(s) => format!("{s:?}"),
        Value::Int(i) => i.to_string(),
        Value::Dict(d) => format!("a dict of {} entries", d.len()),
        Value::List(l) => format!("a list of {} items", l.len()),
        Value::Tuple(t) => format!("a tuple of {} items", t.len()),
        Value::Object(c) => format!("an object of class {c}"),
        Value::Tensor(t) => format!("a tensor {:?}", t.shape),
        other => format!("{other:?}"),
    }
}

/// Largest tensor accepted (2^30 elements, 4 GiB of f32): a view can
/// repeat storage elements (stride 0), so the file size alone does not bound it.
const MAX_ELEMENTS: usize = 1 << 30;

/// Copies a (possibly strided) tensor view out of its storage bytes.
fn gather(t: &TensorRef, storage: &[u8]) -> Result<StoredTensor, String> {
    let dtype = DType::from_torch_storage(&t.storage_type)
        .ok_or_else(|| format!("unsupported storage type {}", t.storage_type))?;
    if t.shape.len() != t.stride.len() {
        return Err(format!(
            "size {:?} and stride {:?} differ in length",
            t.shape, t.stride
        ));
    }
    let es = dtype.size();
    let storage_len = storage.len() / es;
    let too_big = || {
        format!(
            "shape {:?} with stride {:?} is too large",
            t.shape, t.stride
        )
    };
    let numel = t
        .shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&n| n <= MAX_ELEMENTS)
        .ok_or_else(too_big)?;
    if numel > 0 {
        let last = t
            .shape
            .iter()
            .zip(&t.stride)
            .try_fold(t.storage_offset, |a, (s, st)| {
                a.checked_add((s - 1).checked_mul(*st)?)
            })
            .ok_or_else(too_big)?;
        if last >= storage_len {
            return Err(format!(
                "view of shape {:?} (offset {}, stride {:?}) reaches element {last}, \
                 but the storage holds {storage_len} (truncated file?)",
                t.shape, t.storage_offset, t.stride
            ));
        }
    }
    let mut data = Vec::with_capacity(numel);
    let mut index = vec![0usize; t.shape.len()];
    for _ in 0..numel {
        let at = t.storage_offset
            + index
                .iter()
                .zip(&t.stride)
                .map(|(i, s)| i * s)
                .sum::<usize>();
        data.push(dtype.decode(&storage[at * es..(at + 1) * es]));
        // odometer increment, last axis fastest (C order)
        for ax in (0..index.len()).rev() {
            index[ax] += 1;
            if index[ax] < t.shape[ax] {
                break;
            }
            index[ax] = 0;
        }
    }
    let tensor = Tensor::new(t.shape.clone(), data).map_err(|e| e.to_string())?;
    Ok(StoredTensor { dtype, tensor })
}
