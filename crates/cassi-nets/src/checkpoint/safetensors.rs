//! `.safetensors`: an 8-byte little-endian header length, a JSON header
//! `{name: {dtype, shape, data_offsets: [begin, end]}, "__metadata__": …}`,
//! then the raw little-endian tensor bytes.

use super::StoredTensor;
use super::dtype::DType;
use crate::tensor::Tensor;

pub(crate) fn read(bytes: &[u8]) -> Result<Vec<(String, StoredTensor)>, String> {
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
    let data = &bytes[data_start as usize..];
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
        let t = parse_entry(&info, data).map_err(|e| format!("tensor {name}: {e}"))?;
        out.push((name, t));
    }
    Ok(out)
}

fn parse_entry(info: &serde_json::Value, data: &[u8]) -> Result<StoredTensor, String> {
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
    let numel = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or("shape overflows")?;
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
    let raw = &data[begin as usize..end as usize];
    let values = raw
        .chunks_exact(dtype.size())
        .map(|b| dtype.decode(b))
        .collect();
    let tensor = Tensor::new(shape, values).map_err(|e| e.to_string())?;
    Ok(StoredTensor { dtype, tensor })
}
