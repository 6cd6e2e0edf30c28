//! `.safetensors`: an 8-byte little-endian header length, a JSON header
//! `{name: {dtype, shape, data_offsets: [begin, end]}, "__metadata__": …}`,
//! then the raw little-endian tensor bytes.

use std::sync::Arc;

use cassi_core::limits;

use super::dtype::DType;
use super::{Entry, View};

pub(crate) fn read(all: &Arc<Vec<u8>>) -> Result<Vec<(String, Entry)>, String> {
    let bytes = all.as_slice();
    let not_st = "neither a PyTorch zip checkpoint nor a safetensors file";
    let Some(len_bytes) = bytes.get(..8) else {
        return Err(format!("{not_st} (only {} bytes)", bytes.len()));
    };
    let header_len = u64::from_le_bytes(len_bytes.try_into().unwrap_or([0; 8]));
    let data_start = 8u64.saturating_add(header_len);
    if data_start > bytes.len() as u64 {
        return Err(format!(
            "{not_st}, or a truncated one: header length {header_len} exceeds the file size {}",
            bytes.len()
        ));
    }
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..data_start as usize])
        .map_err(|e| format!("{not_st} (safetensors header is not JSON: {e})"))?;
    let serde_json::Value::Object(entries) = header else {
        return Err("safetensors header is not a JSON object".into());
    };

    let mut out = Vec::with_capacity(entries.len());
    for (name, info) in entries {
        if name == "__metadata__" {
            continue;
        }
        let t = parse_entry(&name, &info, all, data_start as usize)
            .map_err(|e| format!("tensor {name}: {e}"))?;
        out.push((name, t));
    }
    Ok(out)
}

/// Checks one header entry (type, element budget, offsets within the data)
/// without decoding its values.
fn parse_entry(
    name: &str,
    info: &serde_json::Value,
    all: &Arc<Vec<u8>>,
    data_start: usize,
) -> Result<Entry, String> {
    let data = &all[data_start..];
    let dtype_name = info["dtype"].as_str().ok_or("no dtype")?;
    let dtype = DType::from_safetensors(dtype_name)
        .ok_or_else(|| format!("unsupported dtype {dtype_name}"))?;
    let shape: Vec<usize> = info["shape"]
        .as_array()
        .ok_or("no shape")?
        .iter()
        .map(|d| {
            d.as_u64()
                .map(|d| d as usize)
                .ok_or("shape entry is not an integer")
        })
        .collect::<Result<_, _>>()?;
    let offsets = info["data_offsets"].as_array().ok_or("no data_offsets")?;
    let (Some(begin), Some(end), 2) = (
        offsets.first().and_then(|v| v.as_u64()),
        offsets.get(1).and_then(|v| v.as_u64()),
        offsets.len(),
    ) else {
        return Err("data_offsets is not [begin, end]".into());
    };
    let numel = limits::check_elements(
        &format!("tensor {name} ({dtype_name})"),
        &shape,
        "declared in the safetensors header",
    )
    .map_err(|e| e.to_string())?;
    let want = (numel as u64).saturating_mul(dtype.size() as u64);
    if end < begin || end - begin != want {
        return Err(format!(
            "data_offsets [{begin}, {end}] hold {} bytes, but shape {shape:?} of {dtype_name} needs {want}",
            end.saturating_sub(begin)
        ));
    }
    if end > data.len() as u64 {
        return Err(format!(
            "data ends at byte {end} of the data section, which has only {} (truncated file?)",
            data.len()
        ));
    }
    let mut stride = vec![1usize; shape.len()];
    for d in (0..shape.len().saturating_sub(1)).rev() {
        stride[d] = stride[d + 1] * shape[d + 1];
    }
    Ok(Entry::lazy(
        dtype,
        shape,
        View {
            bytes: Arc::clone(all),
            start: data_start + begin as usize,
            len: (end - begin) as usize,
            offset: 0,
            stride,
        },
    ))
}
