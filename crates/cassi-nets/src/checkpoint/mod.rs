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

/// One tensor of a checkpoint, converted to f32, with its stored type.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredTensor {
    pub dtype: DType,
    pub tensor: Tensor,
}

/// The named tensors of one checkpoint file (a state dict).
#[derive(Debug, Clone)]
pub struct TensorMap {
    path: PathBuf,
    tensors: BTreeMap<String, StoredTensor>,
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
            msg,
        })?;
        Ok(Self::from_named(path.to_path_buf(), tensors))
    }

    /// Builds a map from named tensors, stripping a `module.` prefix common to all.
    pub fn from_named(path: PathBuf, named: Vec<(String, StoredTensor)>) -> Self {
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
    /// Total number of elements over all tensors.
    pub fn parameter_count(&self) -> usize {
        self.tensors.values().map(|t| t.tensor.numel()).sum()
    }
    pub fn get(&self, name: &str) -> Option<&StoredTensor> {
        self.tensors.get(name)
    }
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.tensors.keys().map(String::as_str)
    }
    pub fn iter(&self) -> impl Iterator<Item = (&str, &StoredTensor)> {
        self.tensors.iter().map(|(n, t)| (n.as_str(), t))
    }
    pub(crate) fn remove(&mut self, name: &str) -> Option<StoredTensor> {
        self.tensors.remove(name)
    }

    /// Replaces tensors by those of `over` (e.g. a partial override file).
    /// Every tensor of `over` must already exist here with the same shape;
    /// otherwise one error lists the offending names.
    pub fn overlay(&mut self, over: TensorMap) -> Result<()> {
        let mut problems = Vec::new();
        for (name, t) in &over.tensors {
            match self.tensors.get(name) {
                None => problems.push(format!(
                    "  unexpected: {name} {}",
                    shape_str(t.tensor.shape())
                )),
                Some(base) if base.tensor.shape() != t.tensor.shape() => problems.push(format!(
                    "  wrong shape: {name}: got {}, wanted {}",
                    shape_str(t.tensor.shape()),
                    shape_str(base.tensor.shape())
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
