//! The dispersion stage of the `default` preset for the `subpixel` model,
//! where a1 and α act continuously.
//!
//! Stage 2 fits (dx, dy, θ) at the nominal a1 = 2, α = 0. With a drifted a1
//! it aligned dx with *some* group of bands, so a candidate a1 is tried with
//! dx moved to keep band 0, the middle band or the last band in place (three
//! hypotheses per a1). α tilts the spectrum off the rows: band k moves down
//! by a1·k·sin α, which stage 2 could only absorb into dy, so α is scanned
//! with dy moved to keep the middle band's row.

use crate::params::Mismatch;

/// Every scored hypothesis as (score, ψ), best first, and the count.
pub(crate) fn subpixel_dispersion(
    search: &dyn Fn(&Mismatch) -> f64,
    from: &Mismatch,
    bands: usize,
    (lo, hi): (f64, f64),
    alpha_range_deg: f64,
) -> (Vec<(f64, Mismatch)>, usize) {
    let last = bands.saturating_sub(1) as f64;
    let mut scored: Vec<(f64, Mismatch)> = Vec::new();
    let consider = |m: Mismatch, scored: &mut Vec<(f64, Mismatch)>| scored.push((search(&m), m));
    // a1 grid (step 0.01) × which band stage 2 kept in place
    let steps = ((hi - lo) / 0.01).round().max(1.0) as usize;
    let c = from.alpha_deg.to_radians().cos();
    for j in 0..=steps {
        let a1 = lo + (hi - lo) * j as f64 / steps as f64;
        for k_ref in [0.0, 0.5 * last, last] {
            let m = Mismatch {
                a1,
                dx: from.dx - (a1 - from.a1) * k_ref * c,
                ..*from
            };
            consider(m, &mut scored);
        }
    }
    // α scan (step 0.25°), the middle band's row held
    let base = scored
        .iter()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or(*from, |c| c.1);
    let row_mid = |m: &Mismatch| m.dy + m.a1 * 0.5 * last * m.alpha_deg.to_radians().sin();
    let n = (alpha_range_deg / 0.25).round() as i64;
    for i in -n..=n {
        let alpha_deg = 0.25 * i as f64;
        if alpha_deg == base.alpha_deg {
            continue;
        }
        let mut m = Mismatch { alpha_deg, ..base };
        m.dy += row_mid(&base) - row_mid(&m);
        consider(m, &mut scored);
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let evals = scored.len();
    (scored, evals)
}
