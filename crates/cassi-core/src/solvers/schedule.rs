//! How the denoiser's strength evolves over the iterations.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Strength {
    /// The same strength every iteration.
    Constant { value: f32 },
    /// Geometric interpolation from `start` (first iteration) to `end` (last):
    /// strong smoothing early, fine detail late.
    Geometric { start: f32, end: f32 },
}

impl Strength {
    /// Strength at 0-based iteration `i` of `n`.
    pub fn at(&self, i: usize, n: usize) -> f32 {
        match *self {
            Strength::Constant { value } => value,
            Strength::Geometric { start, end } => {
                if n <= 1 {
                    return start;
                }
                let t = i as f32 / (n - 1) as f32;
                start * (end / start).powf(t)
            }
        }
    }

    pub fn validate(&self) -> crate::Result<()> {
        let ok = |v: f32| v.is_finite() && v >= 0.0;
        let (good, v) = match *self {
            Strength::Constant { value } => (ok(value), value),
            Strength::Geometric { start, end } => (
                ok(start) && ok(end) && start > 0.0 && end > 0.0,
                start.min(end),
            ),
        };
        if good {
            Ok(())
        } else {
            Err(crate::CassiError::InvalidParameter {
                name: "strength",
                value: v as f64,
                reason: "denoiser strengths must be finite and ≥ 0 (> 0 for a geometric schedule)"
                    .into(),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometric_runs_from_start_to_end() {
        let s = Strength::Geometric {
            start: 1.0,
            end: 0.01,
        };
        assert!((s.at(0, 5) - 1.0).abs() < 1e-6);
        assert!((s.at(2, 5) - 0.1).abs() < 1e-6);
        assert!((s.at(4, 5) - 0.01).abs() < 1e-6);
        assert!(Strength::Constant { value: -1.0 }.validate().is_err());
    }
}
