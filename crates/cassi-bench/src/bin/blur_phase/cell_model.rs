//! A prototype of the fix `blur_phase` points to, for θ = α = 0 only: the
//! instrument as a sum of mask cells, each a crisp square of value
//! M_ij · x_k(its centre) (the share of it over the scene), blurred and
//! integrated at its own offset on the detector. Slow (every cell of every
//! band) and without derivatives: a measurement of what the model would
//! gain, not an operator.

use cassi_bench::{golden_section, relative_residual2};
use cassi_core::optics::pixel_kernel as kernel;
use cassi_core::{Cube, Mask, Mismatch};

use super::DETECTOR;

/// The instrument as a sum of mask cells, for θ = α = 0: cell (i, j) of
/// band k is a crisp square of value M_ij · x_k(at its centre), centred on
/// the detector at (i + dy, j + dx + a1·k), blurred and integrated:
/// (G∗tri)(r − i − dy)·(G∗tri)(c − j − dx − a1·k). The model with each
/// band's code blurred at its own fractional offset (what the
/// dispersed-mask model approximates by interpolating the code linearly
/// and blurring after).
pub fn forward(mask: &Mask, scene: &Cube, psi: &Mismatch) -> Vec<f64> {
    let (rows, cols) = mask.shape();
    let (dr, dc) = DETECTOR;
    let sigma = psi.blur_sigma_px;
    let reach = (4.0 * sigma).ceil() as i64 + 2;
    let at = |band: &[f32], r: f64, c: f64| {
        let r = r.clamp(0.0, (rows - 1) as f64);
        let c = c.clamp(0.0, (cols - 1) as f64);
        let (r0, c0) = (r.floor() as usize, c.floor() as usize);
        let (r1, c1) = ((r0 + 1).min(rows - 1), (c0 + 1).min(cols - 1));
        let (fr, fc) = (r - r0 as f64, c - c0 as f64);
        let v = |i: usize, j: usize| band[i * cols + j] as f64;
        (1.0 - fr) * ((1.0 - fc) * v(r0, c0) + fc * v(r0, c1))
            + fr * ((1.0 - fc) * v(r1, c0) + fc * v(r1, c1))
    };
    // every cell of a band sits at the same fraction: one set of taps per
    // band and axis, (offset from the cell's floor, weight)
    let taps = |centre: f64| -> (i64, Vec<(i64, f64)>) {
        let base = centre.floor();
        let taps = (-reach..=reach + 1)
            .map(|t| (t, kernel(sigma, (base + t as f64) - centre)))
            .filter(|&(_, w)| w != 0.0)
            .collect();
        (base as i64, taps)
    };
    let (row_base, row_taps) = taps(psi.dy);
    let mut y = vec![0.0f64; dr * dc];
    let mut q = vec![0.0f64; rows * dc];
    for k in 0..scene.bands() {
        let band = scene.band(k);
        let (col_base, col_taps) = taps(psi.dx + psi.a1 * k as f64);
        q.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..rows {
            for j in 0..cols {
                let m = mask.get(i, j) as f64;
                if m == 0.0 {
                    continue;
                }
                // the share of the cell over the scene (light only there)
                let inside = |centre: f64, n: usize| {
                    ((centre + 0.5).min(n as f64 - 0.5) - (centre - 0.5).max(-0.5)).clamp(0.0, 1.0)
                };
                let share = inside(i as f64 + psi.dy, rows) * inside(j as f64 + psi.dx, cols);
                if share == 0.0 {
                    continue;
                }
                let p = share * m * at(band, i as f64 + psi.dy, j as f64 + psi.dx);
                for &(t, w) in &col_taps {
                    let c = j as i64 + col_base + t;
                    if (0..dc as i64).contains(&c) {
                        q[i * dc + c as usize] += p * w;
                    }
                }
            }
        }
        for i in 0..rows {
            for &(t, w) in &row_taps {
                let r = i as i64 + row_base + t;
                if !(0..dr as i64).contains(&r) {
                    continue;
                }
                let (src, dst) = (&q[i * dc..][..dc], &mut y[r as usize * dc..][..dc]);
                for (o, &v) in dst.iter_mut().zip(src) {
                    *o += w * v;
                }
            }
        }
    }
    y
}

/// The σ this model fits to `y`, everything else at `truth` (golden
/// section on [0, 0.9]).
pub fn fitted_sigma(y: &[f64], mask: &Mask, scene: &Cube, truth: &Mismatch) -> f64 {
    let score = |sigma: f64| {
        let psi = Mismatch {
            blur_sigma_px: sigma,
            ..*truth
        };
        relative_residual2(y, &forward(mask, scene, &psi))
    };
    golden_section(score, (0.0, 0.9), 0.002)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cassi_bench::predict_on_detector;
    use cassi_core::optics::DispersionModel;

    /// Where the dispersed-mask operator is exact — every cell on whole
    /// pixels, sharp or blurred — the prototype must be that operator
    /// (the kernel's integer samples are the blur model's taps); away from
    /// whole pixels with a blur they must differ, or the bench measures
    /// nothing.
    #[test]
    fn the_cell_model_is_the_operator_on_whole_pixels_and_not_between() {
        // 28 bands fill the 310 columns: the model's frame is the detector
        // (with fewer its blur would lose light at a narrower edge)
        let (bands, rows, cols) = (28, 256, 256);
        let mask = cassi_core::synth::random_binary_mask(rows, cols, 0.5, 7).unwrap();
        let scene = Cube::from_vec(
            bands,
            rows,
            cols,
            (0..bands * rows * cols)
                .map(|i| {
                    let (k, r, c) = (i / (rows * cols), i / cols % rows, i % cols);
                    0.6 + 0.3 * ((r as f32 * 0.05 + k as f32).sin() * (c as f32 * 0.07).cos())
                })
                .collect(),
        )
        .unwrap();
        let gap = |psi: &Mismatch| {
            let cell = forward(&mask, &scene, psi);
            let model =
                predict_on_detector(&mask, &scene, psi, DispersionModel::DispersedMask, DETECTOR)
                    .unwrap();
            relative_residual2(&model, &cell).sqrt()
        };
        for (dx, dy, sigma) in [
            (0.0, 0.0, 0.0),
            (0.0, 0.0, 0.5),
            (1.0, -1.0, 0.5),
            (2.0, 1.0, 0.3),
        ] {
            let psi = Mismatch {
                dx,
                dy,
                blur_sigma_px: sigma,
                ..Mismatch::nominal(2.0)
            };
            assert!(gap(&psi) < 1e-4, "dx {dx} dy {dy} σ {sigma}: {}", gap(&psi));
        }
        let between = Mismatch {
            dy: 0.5,
            blur_sigma_px: 0.5,
            ..Mismatch::nominal(2.0)
        };
        assert!(gap(&between) > 1e-3, "{}", gap(&between));
    }
}
