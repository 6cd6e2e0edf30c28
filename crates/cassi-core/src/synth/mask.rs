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

/// A grey mask for operator tests: values uniform in [0, 1), row-major from
/// `Rng::new(seed)`.
#[cfg(test)]
pub(crate) fn uniform_grey_mask(rows: usize, cols: usize, seed: u64) -> Mask {
    let mut rng = Rng::new(seed);
    let data = (0..rows * cols).map(|_| rng.uniform() as f32).collect();
    Mask::from_vec(rows, cols, data).expect("rows × cols values")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_with_requested_open_fraction() {
        for (p, seed) in [(0.5, 0), (0.2, 1), (0.85, 2)] {
            let m = random_binary_mask(200, 150, p, seed).unwrap();
            assert_eq!(m.shape(), (200, 150));
            assert!(m.as_slice().iter().all(|&v| v == 0.0 || v == 1.0));
            let n = m.as_slice().len() as f64;
            let frac = m.as_slice().iter().map(|&v| f64::from(v)).sum::<f64>() / n;
            let sigma = (p * (1.0 - p) / n).sqrt();
            assert!((frac - p).abs() < 4.0 * sigma, "p {p}: got {frac}");
        }
    }

    #[test]
    fn unstructured_rows_and_columns() {
        // i.i.d.: no row or column is far off the mean, and neighbours are
        // uncorrelated.
        let m = random_binary_mask(256, 256, 0.5, 7).unwrap();
        let (mut same, mut pairs) = (0usize, 0usize);
        for r in 0..256 {
            let row = m.row(r);
            let s: f32 = row.iter().sum();
            assert!((s - 128.0).abs() < 40.0, "row {r}: {s}");
            for c in 0..255 {
                same += usize::from(row[c] == row[c + 1]);
                pairs += 1;
            }
        }
        for c in 0..256 {
            let s: f32 = (0..256).map(|r| m.get(r, c)).sum();
            assert!((s - 128.0).abs() < 40.0, "col {c}: {s}");
        }
        let agree = same as f64 / pairs as f64;
        assert!((agree - 0.5).abs() < 0.01, "neighbour agreement {agree}");
    }

    #[test]
    fn deterministic_and_seed_dependent() {
        let a = random_binary_mask(64, 48, 0.5, 11).unwrap();
        assert_eq!(a, random_binary_mask(64, 48, 0.5, 11).unwrap());
        let b = random_binary_mask(64, 48, 0.5, 12).unwrap();
        let differ = a
            .as_slice()
            .iter()
            .zip(b.as_slice())
            .filter(|(x, y)| x != y)
            .count();
        assert!(differ > 64 * 48 / 3, "{differ}");
        // A taller mask extends a shorter one with the same seed and width.
        let tall = random_binary_mask(80, 48, 0.5, 11).unwrap();
        assert_eq!(&tall.as_slice()[..64 * 48], a.as_slice());
        // Pinned first row bits, so a change of the generator is noticed.
        let bits: u64 = a
            .row(0)
            .iter()
            .enumerate()
            .map(|(i, &v)| (v as u64) << i)
            .sum();
        assert_eq!(
            bits, PINNED_ROW0,
            "mask generator output changed: {bits:#x}"
        );
    }

    const PINNED_ROW0: u64 = 0xddb0_67fc_4566;

    #[test]
    fn bad_arguments_are_errors() {
        for p in [0.0, 1.0, -0.1, 1.5, f64::NAN] {
            assert!(random_binary_mask(4, 4, p, 0).is_err(), "{p}");
        }
        assert!(random_binary_mask(0, 4, 0.5, 0).is_err());
        assert!(random_binary_mask(4, 0, 0.5, 0).is_err());
        assert!(random_binary_mask(1, 1, 0.5, 0).is_ok());
    }
}
