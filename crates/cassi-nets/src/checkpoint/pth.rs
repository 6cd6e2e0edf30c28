//! PyTorch zip checkpoints (`torch.save` since 1.6): `<root>/data.pkl` holds
//! the pickled state dict, `<root>/data/<key>` the raw bytes of each storage.

use std::collections::HashMap;
use std::io::{Cursor, Read};
use std::sync::Arc;

use cassi_core::limits;

use super::dtype::DType;
use super::pickle::{TensorRef, Value, unpickle};
use super::{Entry, View};

/// Keys under which training scripts commonly nest the state dict.
const NESTED_STATE_DICT_KEYS: [&str; 4] = ["state_dict", "model_state_dict", "model", "net"];

pub(crate) fn read(bytes: &Arc<Vec<u8>>) -> Result<Vec<(String, Entry)>, String> {
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes.as_slice()))
        .map_err(|e| format!("not a readable PyTorch zip checkpoint: {e}"))?;
    let pkl_name = zip
        .file_names()
        .find(|n| *n == "data.pkl" || n.ends_with("/data.pkl"))
        .map(str::to_string)
        .ok_or("a zip archive without data.pkl: not a PyTorch checkpoint")?;
    let root = &pkl_name[..pkl_name.len() - "data.pkl".len()];
    if let Ok(f) = zip.by_name(&format!("{root}byteorder")) {
        let mut order = String::new();
        f.take(64).read_to_string(&mut order).ok();
        if order.trim() != "little" {
            return Err(format!(
                "byte order {:?} is not supported (only little)",
                order.trim()
            ));
        }
    }
    let pkl = read_entry(&mut zip, &pkl_name)?;
    let top = unpickle(&pkl)?;
    drop(pkl);
    let entries = state_dict_entries(top)?;

    // Every header is checked (budget, storage size, view extent) before any
    // value is decoded; the values stay in the file's bytes until asked for.
    let mut storages: HashMap<String, (usize, usize)> = HashMap::new();
    let mut out = Vec::with_capacity(entries.len());
    for (name, t) in entries {
        let range = match storages.get(&t.storage_key) {
            Some(r) => *r,
            None => {
                let r = stored_range(
                    &mut zip,
                    &format!("{root}data/{}", t.storage_key),
                    bytes.len(),
                )
                .map_err(|e| format!("tensor {name}: {e}"))?;
                storages.insert(t.storage_key.clone(), r);
                r
            }
        };
        let entry = check_view(&name, &t, bytes, range)?;
        out.push((name, entry));
    }
    Ok(out)
}

/// The byte range of a stored (uncompressed, as torch.save writes them)
/// zip member, checked to lie within the file.
fn stored_range(
    zip: &mut zip::ZipArchive<Cursor<&[u8]>>,
    name: &str,
    file_len: usize,
) -> Result<(usize, usize), String> {
    let f = zip
        .by_name(name)
        .map_err(|e| format!("zip entry {name}: {e}"))?;
    if f.compression() != zip::CompressionMethod::Stored {
        return Err(format!(
            "zip entry {name} is compressed ({}); torch.save stores tensor data uncompressed",
            f.compression()
        ));
    }
    let (start, size) = (f.data_start(), f.compressed_size());
    if f.size() != size || start.saturating_add(size) > file_len as u64 {
        return Err(format!(
            "zip entry {name} declares {} bytes at byte {start}, but the file has {file_len} \
             (truncated file?)",
            f.size()
        ));
    }
    Ok((start as usize, size as usize))
}

fn read_entry(zip: &mut zip::ZipArchive<Cursor<&[u8]>>, name: &str) -> Result<Vec<u8>, String> {
    let archive_len = zip.clone().into_inner().into_inner().len() as u64;
    let f = zip
        .by_name(name)
        .map_err(|e| format!("zip entry {name}: {e}"))?;
    // The declared size can lie; the archive's own length bounds a stored
    // entry, and the read is capped at it.
    let cap = f.size().min(archive_len);
    let mut buf = Vec::with_capacity(cap as usize);
    f.take(cap)
        .read_to_end(&mut buf)
        .map_err(|e| format!("zip entry {name} is unreadable (truncated file?): {e}"))?;
    Ok(buf)
}

/// Checks a tensor's header before anything is decoded: a storage type we
/// read, an element count within the budget of [`cassi_core::limits`], a
/// storage no larger than its zip member, and a view (offset + Σ (size − 1)
/// · stride) that ends inside its storage.
fn check_view(
    name: &str,
    t: &TensorRef,
    bytes: &Arc<Vec<u8>>,
    (start, len): (usize, usize),
) -> Result<Entry, String> {
    let fail = |e: String| format!("tensor {name}: {e}");
    let dtype = DType::from_torch_storage(&t.storage_type)
        .ok_or_else(|| fail(format!("unsupported storage type {}", t.storage_type)))?;
    if t.shape.len() != t.stride.len() {
        return Err(fail(format!(
            "size {:?} and stride {:?} differ in length",
            t.shape, t.stride
        )));
    }
    let numel = limits::check_elements(
        &format!("tensor {name} ({})", t.storage_type),
        &t.shape,
        &format!("declared in data.pkl with stride {:?}", t.stride),
    )
    .map_err(|e| e.to_string())?;
    let es = dtype.size();
    let mut storage_len = len / es;
    if let Some(n) = t.storage_numel {
        if n > storage_len {
            return Err(fail(format!(
                "storage {} declares {n} elements ({} bytes) but its zip member holds {len} bytes \
                 (truncated file?)",
                t.storage_key,
                n.saturating_mul(es)
            )));
        }
        storage_len = n;
    }
    if numel > 0 {
        let last = t
            .shape
            .iter()
            .zip(&t.stride)
            .try_fold(t.storage_offset, |a, (s, st)| {
                a.checked_add((s - 1).checked_mul(*st)?)
            })
            .ok_or_else(|| {
                fail(format!(
                    "shape {:?} with stride {:?} is too large",
                    t.shape, t.stride
                ))
            })?;
        if last >= storage_len {
            return Err(fail(format!(
                "view of shape {:?} (offset {}, stride {:?}) reaches element {last}, \
                 but the storage holds {storage_len} (truncated file?)",
                t.shape, t.storage_offset, t.stride
            )));
        }
    }
    Ok(Entry::lazy(
        dtype,
        t.shape.clone(),
        View {
            bytes: Arc::clone(bytes),
            start,
            len,
            offset: t.storage_offset,
            stride: t.stride.clone(),
        },
    ))
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
