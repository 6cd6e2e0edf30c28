//! The dispersion stage of the `default` preset for the `rounded` model,
//! where a1 and α act only through the rounding pattern of the band offsets
//! (round(d_k·cos α) columns, round(d_k·sin α) rows, d_k = a1·k + a2·k² with
//! the curvature a2 the calibration holds, 0 unless given).
//!
//! Stage 2 fitted (dx, dy) at the nominal pattern (2k, 0); with a drifted
//! a1 or α it aligned the mask with *some* group of bands. A candidate
//! pattern moves band k by (δc_k, δr_k) relative to the nominal one, so the
//! matching mask shift is (dx − δc, dy − δr) for one of the distinct
//! (δc_k, δr_k): each is tried, and the midpoint of each consecutive pair
//! (stage 2 can settle halfway between two groups). a1 is searched over the exact rounding
//! intervals (coarse: those holding an a1 grid; fine: every interval within
//! a window around the best); then α over a grid at the best
//! a1, where only angles that change the row pattern are scored (|α| ≲ 0.5°
//! leaves every row offset at 0 for 28 bands).

use std::collections::HashSet;

use crate::params::{DispersionParams, Mismatch};

/// Every band's rounded (col, row) offset, with the curvature `a2` the
/// calibration holds.
fn pattern(a1: f64, alpha_deg: f64, a2: f64, bands: usize) -> Vec<(i64, i64)> {
    let (s, c) = alpha_deg.to_radians().sin_cos();
    let shape = DispersionParams { a1, alpha_deg, a2 };
    (0..bands)
        .map(|k| {
            let along = shape.along(k as f64);
            (
                (along * c).round_ties_even() as i64,
                (along * s).round_ties_even() as i64,
            )
        })
        .collect()
}

/// The breakpoints where some band's rounded column offset changes: a1
/// values with (a1·k + a2·k²)·cos α = j + ½. Between two consecutive ones
/// the rounded model is the same operator.
pub(crate) fn rounding_intervals(
    bands: usize,
    alpha_deg: f64,
    a2: f64,
    lo: f64,
    hi: f64,
) -> Vec<(f64, f64)> {
    let c = alpha_deg.to_radians().cos();
    let mut cuts = vec![lo, hi];
    for k in 1..bands {
        let kc = k as f64 * c;
        // the curvature's share of band k's column offset
        let bend = a2 * (k * k) as f64 * c;
        let (jlo, jhi) = (
            (lo * kc + bend - 0.5).floor() as i64,
            (hi * kc + bend - 0.5).ceil() as i64,
        );
        for j in jlo..=jhi {
            let a = (j as f64 + 0.5 - bend) / kc;
            if a > lo && a < hi {
                cuts.push(a);
            }
        }
    }
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    cuts.windows(2).map(|w| (w[0], w[1])).collect()
}

/// Every scored hypothesis as (score, ψ), best first (one evaluation each).
pub(crate) fn rounded_dispersion(
    search: &dyn Fn(&Mismatch) -> f64,
    from: &Mismatch,
    bands: usize,
    (lo, hi): (f64, f64),
    (grid_step, fine_window): (f64, f64),
    (alpha_range_deg, alpha_step_deg): (f64, f64),
) -> Vec<(f64, Mismatch)> {
    let mut tried: HashSet<Vec<(i64, i64)>> = HashSet::new();
    let mut scored: Vec<(f64, Mismatch)> = Vec::new();
    // hypotheses for the pattern of (a1, α), shifts relative to `base`
    let mut try_pattern =
        |a1: f64, alpha_deg: f64, base: &Mismatch, scored: &mut Vec<(f64, Mismatch)>| {
            let p = pattern(a1, alpha_deg, base.a2, bands);
            if !tried.insert(p.clone()) {
                return;
            }
            let mut deltas: Vec<(i64, i64)> = p
                .iter()
                .zip(&pattern(base.a1, base.alpha_deg, base.a2, bands))
                .map(|(a, b)| (a.0 - b.0, a.1 - b.1))
                .collect();
            deltas.sort_unstable();
            deltas.dedup();
            // stage 2 may also have settled halfway between two band groups
            // (a1 near a rounding break, when both carry similar light)
            let mut shifts: Vec<(f64, f64)> =
                deltas.iter().map(|&(c, r)| (c as f64, r as f64)).collect();
            shifts.extend(deltas.windows(2).map(|w| {
                (
                    0.5 * (w[0].0 + w[1].0) as f64,
                    0.5 * (w[0].1 + w[1].1) as f64,
                )
            }));
            for (dc, dr) in shifts {
                let m = Mismatch {
                    a1,
                    alpha_deg,
                    dx: base.dx - dc,
                    dy: base.dy - dr,
                    ..*base
                };
                scored.push((search(&m), m));
            }
        };
    let best_of = |scored: &[(f64, Mismatch)]| {
        scored
            .iter()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(*from, |c| c.1)
    };
    // a1 at the current α: coarse grid, then every interval near the best
    let intervals = rounding_intervals(bands, from.alpha_deg, from.a2, lo, hi);
    let mid = |i: usize| 0.5 * (intervals[i].0 + intervals[i].1);
    let steps = ((hi - lo) / grid_step).round().max(1.0) as usize;
    for j in 0..=steps {
        let g = lo + (hi - lo) * j as f64 / steps as f64;
        if let Some(i) = intervals.iter().position(|&(a, b)| a <= g && g <= b) {
            try_pattern(mid(i), from.alpha_deg, from, &mut scored);
        }
    }
    let centre = best_of(&scored).a1;
    for &(a, b) in &intervals {
        if b >= centre - fine_window && a <= centre + fine_window {
            try_pattern(0.5 * (a + b), from.alpha_deg, from, &mut scored);
        }
    }
    // α at the best a1, shifts relative to its hypothesis (its columns are
    // aligned; α moves rows); patterns already scored are skipped
    let base = best_of(&scored);
    let n = (alpha_range_deg / alpha_step_deg).round() as i64;
    for i in -n..=n {
        try_pattern(base.a1, alpha_step_deg * i as f64, &base, &mut scored);
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    scored
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_intervals_cover_the_range_and_break_where_offsets_change() {
        let iv = rounding_intervals(28, 0.0, 0.0, 1.9, 2.1);
        assert_eq!(iv.first().unwrap().0, 1.9);
        assert_eq!(iv.last().unwrap().1, 2.1);
        // a1 = 2.04 lies in the interval [26.5/13, 24.5/12] = [2.03846, 2.04167]
        let hit = iv.iter().find(|(a, b)| *a <= 2.04 && 2.04 < *b).unwrap();
        assert!(
            (hit.0 - 26.5 / 13.0).abs() < 1e-12 && (hit.1 - 24.5 / 12.0).abs() < 1e-12,
            "{hit:?}"
        );
    }

    /// With a curvature held, the intervals are still exactly where the
    /// rounded pattern changes: one pattern across each, another across
    /// the next.
    #[test]
    fn a_curved_dispersion_s_intervals_break_where_its_pattern_changes() {
        let (a2, alpha) = (-0.008, 0.3);
        let iv = rounding_intervals(28, alpha, a2, 1.95, 2.25);
        assert!(iv.len() > 20, "{}", iv.len());
        for w in iv.windows(2) {
            let ((a, b), (_, d)) = (w[0], w[1]);
            let inside = |t: f64| pattern(a + t * (b - a), alpha, a2, 28);
            assert_eq!(inside(0.01), inside(0.99), "[{a}, {b}]");
            assert_ne!(inside(0.5), pattern(0.5 * (b + d), alpha, a2, 28), "at {b}");
        }
        // the straight dispersion's intervals are not these
        assert_ne!(iv, rounding_intervals(28, alpha, 0.0, 1.95, 2.25));
    }

    #[test]
    fn a1_hypotheses_move_the_mask_by_each_band_groups_offset_change() {
        // from the nominal pattern, a1 = 2.04 moves bands 13–27 one column:
        // the hypotheses for its interval are dx and dx − 1
        let from = Mismatch::nominal(2.0);
        let seen = std::cell::RefCell::new(Vec::new());
        let search = |m: &Mismatch| {
            seen.borrow_mut().push(*m);
            (m.a1 - 2.04).abs() + (m.dx + 1.0).abs()
        };
        let scored =
            rounded_dispersion(&search, &from, 28, (1.98, 2.06), (0.01, 0.012), (1.0, 0.25));
        // one evaluation per returned hypothesis
        assert_eq!(scored.len(), seen.borrow().len());
        let best = scored[0].1;
        assert!(
            (2.03846..2.04167).contains(&best.a1) && best.dx == -1.0,
            "{best:?}"
        );
        // α = ±1° moves the upper bands one row: dy − 1 / dy + 1 hypotheses exist
        assert!(
            seen.borrow()
                .iter()
                .any(|m| m.alpha_deg == 1.0 && m.dy == -1.0)
        );
        assert!(
            seen.borrow()
                .iter()
                .any(|m| m.alpha_deg == -1.0 && m.dy == 1.0)
        );
    }
}
