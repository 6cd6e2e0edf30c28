//! Checkpoints: PyTorch state dicts (`.pth`, zip format) and `.safetensors`
//! files, read into a [`TensorMap`], then matched strictly against what a
//! network expects by a [`WeightLoader`].

mod dtype;
mod pickle;
mod pth;
mod safetensors;
mod strict;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use crate::error::{NetError, Result, shape_str};
use crate::tensor::Tensor;

pub use dtype::DType;
pub use strict::WeightLoader;

/// Start of a legacy `torch.save` file: pickle protocol 2, then the LONG1
/// magic number 0x1950a86a20f9469cfc6c. (A safetensors header length never
/// starts like this: it would be over 10^17 bytes.)
const LEGACY_TORCH_MAGIC: &[u8] = &[
    0x80, 0x02, 0x8a, 0x0a, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8,
];

/// `s` with control and text-direction characters written as `\u{1b}`:
/// tensor names come from the file, and error messages quote them, so raw
/// they could drive the user's terminal.
pub(crate) fn esc(s: &str) -> String {
    let bad = |c: char| {
        c.is_control()
            || matches!(c, '\u{061c}' | '\u{200b}'..='\u{200f}' | '\u{2028}'..='\u{202e}' | '\u{2066}'..='\u{2069}' | '\u{feff}')
    };
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if bad(c) {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    out
}

/// One tensor of a checkpoint, converted to f32, with its stored type.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredTensor {
    pub dtype: DType,
    pub tensor: Tensor,
}

/// Where a tensor's values are in the checkpoint's bytes, checked when the
/// file was read: the view (offset, strides) lies within its storage, which
/// lies within the file, and its element count is within the budget of
/// [`cassi_core::limits`]. Materialising it cannot fail.
#[derive(Debug, Clone)]
pub(crate) struct View {
    pub bytes: Arc<Vec<u8>>,
    /// Byte range of the storage in `bytes`.
    pub start: usize,
    pub len: usize,
    /// Element offset and strides of the view into the storage.
    pub offset: usize,
    pub stride: Vec<usize>,
}

/// One tensor of a map: its header (type, shape) and, once asked for, its
/// values. Headers are all a strict load needs to check names and shapes;
/// values are decoded only for tensors that are taken or looked at.
#[derive(Debug, Clone)]
pub(crate) struct Entry {
    pub dtype: DType,
    pub shape: Vec<usize>,
    view: Option<View>,
    cell: OnceLock<StoredTensor>,
}

impl Entry {
    pub(crate) fn lazy(dtype: DType, shape: Vec<usize>, view: View) -> Self {
        Entry {
            dtype,
            shape,
            view: Some(view),
            cell: OnceLock::new(),
        }
    }

    fn ready(t: StoredTensor) -> Self {
        Entry {
            dtype: t.dtype,
            shape: t.tensor.shape().to_vec(),
            view: None,
            cell: OnceLock::from(t),
        }
    }

    pub(crate) fn numel(&self) -> usize {
        self.shape.iter().product()
    }

    fn stored(&self) -> &StoredTensor {
        self.cell.get_or_init(|| self.materialise())
    }

    pub(crate) fn into_stored(mut self) -> StoredTensor {
        match self.cell.take() {
            Some(t) => t,
            None => self.materialise(),
        }
    }

    /// Copies the (possibly strided) view out of its storage, as f32.
    fn materialise(&self) -> StoredTensor {
        let Some(v) = &self.view else {
            return unreachable_zeros(&self.shape);
        };
        let es = self.dtype.size();
        let storage = &v.bytes[v.start..v.start + v.len];
        let numel = self.numel();
        let mut data = Vec::with_capacity(numel);
        let mut index = vec![0usize; self.shape.len()];
        let mut at = v.offset;
        for _ in 0..numel {
            data.push(self.dtype.decode(&storage[at * es..(at + 1) * es]));
            // odometer increment, last axis fastest (C order)
            for ax in (0..index.len()).rev() {
                index[ax] += 1;
                at += v.stride[ax];
                if index[ax] < self.shape[ax] {
                    break;
                }
                at -= self.shape[ax] * v.stride[ax];
                index[ax] = 0;
            }
        }
        let tensor = Tensor::new(self.shape.clone(), data)
            .unwrap_or_else(|_| Tensor::zeros(self.shape.clone()));
        StoredTensor {
            dtype: self.dtype,
            tensor,
        }
    }
}

/// Stands in where an entry has neither values nor a view (never built so).
fn unreachable_zeros(shape: &[usize]) -> StoredTensor {
    StoredTensor {
        dtype: DType::F32,
        tensor: Tensor::zeros(shape.to_vec()),
    }
}

/// The named tensors of one checkpoint file (a state dict). Reading one
/// checks every header (names, types, shapes, where the values lie) against
/// the file and the element budget; values are decoded when a tensor is
/// first asked for, so a strict load ([`WeightLoader`]) never decodes a
/// tensor whose name or shape the network does not want.
#[derive(Debug, Clone)]
pub struct TensorMap {
    path: PathBuf,
    tensors: BTreeMap<String, Entry>,
}

impl TensorMap {
    /// Reads a checkpoint, choosing the format by the file's content (a zip
    /// archive is a PyTorch `.pth`; otherwise safetensors). A `module.`
    /// prefix that every name carries (from `nn.DataParallel`) is removed.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| NetError::Checkpoint {
            path: path.to_path_buf(),
            msg: format!("cannot read: {e}"),
        })?;
        let bytes = Arc::new(bytes);
        let parsed = if bytes.starts_with(b"PK\x03\x04") {
            pth::read(&bytes)
        } else if bytes.starts_with(LEGACY_TORCH_MAGIC) {
            Err(
                "a legacy (pre-1.6, non-zip) torch.save file; re-save it with \
                 torch.save(model.state_dict(), path) from torch >= 1.6"
                    .to_string(),
            )
        } else {
            safetensors::read(&bytes)
        };
        let tensors = parsed.map_err(|msg| NetError::Checkpoint {
            path: path.to_path_buf(),
            msg: esc(&msg),
        })?;
        Ok(Self::from_entries(path.to_path_buf(), tensors))
    }

    /// Builds a map from named tensors, stripping a `module.` prefix common to all.
    pub fn from_named(path: PathBuf, named: Vec<(String, StoredTensor)>) -> Self {
        let entries = named
            .into_iter()
            .map(|(n, t)| (n, Entry::ready(t)))
            .collect();
        Self::from_entries(path, entries)
    }

    fn from_entries(path: PathBuf, named: Vec<(String, Entry)>) -> Self {
        let all_prefixed = !named.is_empty() && named.iter().all(|(n, _)| n.starts_with("module."));
        let tensors = named
            .into_iter()
            .map(|(n, t)| {
                let n = if all_prefixed {
                    n["module.".len()..].to_string()
                } else {
                    n
                };
                (n, t)
            })
            .collect();
        Self { path, tensors }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
    pub fn len(&self) -> usize {
        self.tensors.len()
    }
    pub fn is_empty(&self) -> bool {
        self.tensors.is_empty()
    }
    /// Total number of elements over all tensors (from their headers).
    pub fn parameter_count(&self) -> usize {
        self.tensors.values().map(Entry::numel).sum()
    }
    /// The tensor `name`, decoded on first use.
    pub fn get(&self, name: &str) -> Option<&StoredTensor> {
        self.tensors.get(name).map(Entry::stored)
    }
    /// The stored type and shape of tensor `name`, without decoding it.
    pub fn header(&self, name: &str) -> Option<(DType, &[usize])> {
        self.tensors
            .get(name)
            .map(|e| (e.dtype, e.shape.as_slice()))
    }
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.tensors.keys().map(String::as_str)
    }
    /// Every tensor, decoded on first use.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &StoredTensor)> {
        self.tensors.iter().map(|(n, t)| (n.as_str(), t.stored()))
    }
    pub(crate) fn remove(&mut self, name: &str) -> Option<Entry> {
        self.tensors.remove(name)
    }
    pub(crate) fn headers(&self) -> impl Iterator<Item = (&str, &Entry)> {
        self.tensors.iter().map(|(n, t)| (n.as_str(), t))
    }

    /// Replaces tensors by those of `over` (e.g. a partial override file).
    /// Every tensor of `over` must already exist here with the same shape;
    /// otherwise one error lists the offending names.
    pub fn overlay(&mut self, over: TensorMap) -> Result<()> {
        let mut problems = Vec::new();
        for (name, t) in &over.tensors {
            match self.tensors.get(name) {
                None => problems.push(format!(
                    "  unexpected: {} {}",
                    esc(name),
                    shape_str(&t.shape)
                )),
                Some(base) if base.shape != t.shape => problems.push(format!(
                    "  wrong shape: {}: got {}, wanted {}",
                    esc(name),
                    shape_str(&t.shape),
                    shape_str(&base.shape)
                )),
                Some(_) => {}
            }
        }
        if !problems.is_empty() {
            return Err(NetError::WeightMismatch {
                path: over.path,
                net: format!("the base checkpoint {}", self.path.display()),
                report: problems.join("\n"),
            });
        }
        self.tensors.extend(over.tensors);
        Ok(())
    }
}
