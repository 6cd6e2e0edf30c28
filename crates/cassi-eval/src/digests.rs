//! What a study's per-scene result was computed from, as SHA-256 digests:
//! `--resume` reuses a result only when every digest matches.

use cassi_core::{Cube, Mask};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::protocol::Study;

/// SHA-256 (hex) of what a scene's result was computed from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputDigests {
    /// The scene cube: its shape (bands, rows, cols) and f32 values.
    pub scene: String,
    /// The nominal mask: its shape and values.
    pub mask: String,
    /// Every setting (the study's JSON, the noise seed, the cassi version).
    pub settings: String,
}

impl InputDigests {
    pub fn new(scene: &Cube, mask: &Mask, study: &Study, noise_seed: u64) -> anyhow::Result<Self> {
        let (l, h, w) = scene.shape();
        let settings = serde_json::json!({
            "study": study,
            "noise_seed": noise_seed,
            "cassi_version": env!("CARGO_PKG_VERSION"),
        });
        Ok(Self {
            scene: array_digest(&[l, h, w], scene.as_slice()),
            mask: array_digest(&[mask.rows(), mask.cols()], mask.as_slice()),
            settings: hex(&Sha256::digest(serde_json::to_vec(&settings)?)),
        })
    }

    /// Which inputs differ from `earlier`, in words; `None` when all match.
    pub(crate) fn difference(&self, earlier: &Self) -> Option<String> {
        let differ: Vec<&str> = [
            (self.scene != earlier.scene, "the scene's data"),
            (self.mask != earlier.mask, "the mask's data"),
            (self.settings != earlier.settings, "the settings"),
        ]
        .into_iter()
        .filter_map(|(d, what)| d.then_some(what))
        .collect();
        (!differ.is_empty())
            .then(|| format!("{} differ from the earlier run's", differ.join(" and ")))
    }
}

/// SHA-256 of a shape and its f32 values (little-endian bytes).
fn array_digest(shape: &[usize], values: &[f32]) -> String {
    let mut h = Sha256::new();
    for &d in shape {
        h.update((d as u64).to_le_bytes());
    }
    for v in values {
        h.update(v.to_le_bytes());
    }
    hex(&h.finalize())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
