//! The tilt stage of the `default` preset for the `subpixel` model: α and
//! its coupling with θ.
//!
//! The earlier stages fit the subpixel problem with the rounded model, where
//! α ≲ 0.5° leaves every row offset at 0. A true α displaces band k by
//! d_k·tan α rows; a mask rotation θ displaces the code band k sees by
//! −θ·d_k rows on top of its in-band tilt. So with α pinned at 0 the fit
//! settled on a compromise θ (measured: θ ≈ 0.05–0.08° for a true 0.3°
//! with α = 0.5°) and the right α scores worse there than at 0. Each
//! candidate α is therefore tried with θ moved by κ·α for a few κ, and dy
//! moved to keep the middle band's row.

use crate::params::Mismatch;

/// θ moves tried with each α, as fractions of α (0: θ was right; ½: the
/// measured compromise; 1: θ absorbed all of α's band-to-band tilt).
const THETA_PER_ALPHA: [f64; 3] = [0.0, 0.5, 1.0];

/// Every scored hypothesis as (score, ψ), best first (one evaluation each).
pub(crate) fn subpixel_tilt(
    search: &dyn Fn(&Mismatch) -> f64,
    from: &Mismatch,
    bands: usize,
    alpha_range_deg: f64,
) -> Vec<(f64, Mismatch)> {
    let mid = 0.5 * bands.saturating_sub(1) as f64;
    let row_mid = |m: &Mismatch| m.dy + m.dispersion().along(mid) * m.alpha_deg.to_radians().sin();
    let n = (alpha_range_deg / 0.25).round() as i64;
    let mut scored = vec![(search(from), *from)];
    for i in -n..=n {
        let alpha_deg = 0.25 * i as f64;
        for kappa in THETA_PER_ALPHA {
            let shift = alpha_deg - from.alpha_deg;
            if shift == 0.0 && kappa != 0.0 {
                continue;
            }
            let mut m = Mismatch {
                alpha_deg,
                theta_deg: from.theta_deg + kappa * shift,
                ..*from
            };
            if m == *from {
                continue;
            }
            m.dy += row_mid(from) - row_mid(&m);
            scored.push((search(&m), m));
        }
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    scored
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_is_tried_with_the_theta_it_was_traded_for_and_the_middle_row_held() {
        // the pose fit at α = 0 settled on θ = 0.05 for a truth of
        // (α 0.5°, θ 0.3°): only the hypothesis that moves θ by ½·α reaches it
        let from = Mismatch {
            theta_deg: 0.05,
            a1: 2.04,
            dy: 1.0,
            ..Mismatch::nominal(2.0)
        };
        let truth = (0.5, 0.3);
        let calls = std::cell::Cell::new(0);
        let search = |m: &Mismatch| {
            calls.set(calls.get() + 1);
            (m.alpha_deg - truth.0).abs() + (m.theta_deg - truth.1).abs()
        };
        let scored = subpixel_tilt(&search, &from, 28, 1.0);
        // one evaluation per returned hypothesis
        assert_eq!(calls.get(), scored.len());
        let best = scored[0].1;
        assert!(
            (best.alpha_deg - 0.5).abs() < 1e-12 && (best.theta_deg - 0.3).abs() < 1e-12,
            "{best:?}"
        );
        // band 13.5's row is where it was: dy + a1·13.5·sin α unchanged
        let row = |m: &Mismatch| m.dy + m.a1 * 13.5 * m.alpha_deg.to_radians().sin();
        assert!((row(&best) - row(&from)).abs() < 1e-12);
        assert!(best.dy < from.dy);
        // every α of the ±1° grid is tried (9 angles), with 3 θ moves each but one
        assert_eq!(scored.len(), 1 + 8 * 3);
    }
}
