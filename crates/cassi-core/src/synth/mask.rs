//! Random coded apertures.

use crate::cube::Mask;
use crate::error::{CassiError, Result};
use crate::rng::Rng;

/// Salt for the mask's streams ("mask" in ASCII).
const MASK_SALT: u64 = 0x6d61_736b;

/// An i.i.d. Bernoulli(`open_fraction`) binary mask: each pixel is 1 (open)
/// with probability `open_fraction`, else 0 — the classic random CASSI coded
/// aperture. Row r draws from its own stream of `seed` (salted, so a mask and
/// a scene made with the same seed are unrelated), hence a taller mask with
/// the same seed and `cols` extends a shorter one downward.
///
/// Errors unless `0 < open_fraction < 1` and `rows, cols ≥ 1`.
pub fn random_binary_mask(rows: usize, cols: usize, open_fraction: f64, seed: u64) -> Result<Mask> {
    if !(open_fraction > 0.0 && open_fraction < 1.0) {
        return Err(CassiError::InvalidParameter {
            name: "open_fraction",
            value: open_fraction,
            reason: "the open fraction of a random mask must lie strictly between 0 and 1".into(),
        });
    }
    for (name, v) in [("rows", rows), ("cols", cols)] {
        if v == 0 {
            return Err(CassiError::InvalidParameter {
                name,
                value: 0.0,
                reason: "a mask needs at least one pixel on each side".into(),
            });
        }
    }
    let mut data = Vec::with_capacity(rows * cols);
    for r in 0..rows {
        let mut rng = Rng::stream(seed ^ MASK_SALT, r as u64);
        data.extend((0..cols).map(|_| {
            if rng.uniform() < open_fraction {
                1.0f32
            } else {
                0.0
            }
        }));
    }
    Mask::from_vec(rows, cols, data)
}
