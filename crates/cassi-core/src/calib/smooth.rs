//! Per-band Gaussian smoothing: the proxy solver's prior step (the paper's
//! "TV_σ"). Separable, edge-replicating (no darkening at the border, which
//! would bias the residual near the mask edge), parallel over bands.

use rayon::prelude::*;

use crate::optics::CassiOperator;
use crate::simd::{Simd, kernel};

/// Normalised 1-D Gaussian taps of radius round(3σ) (at least 1): 5 taps
/// for σ = 0.5 and 0.7, 7 for σ = 1, as the paper's kernels.
pub fn gaussian_taps(sigma: f32) -> Vec<f32> {
    let r = (3.0 * sigma).round().max(1.0) as i32;
    let mut t: Vec<f32> = (-r..=r)
        .map(|i| (-0.5 * (i as f32 / sigma).powi(2)).exp())
        .collect();
    let s: f32 = t.iter().sum();
    t.iter_mut().for_each(|v| *v /= s);
    t
}

/// Smooths each (rows × cols) band of `data` in place.
pub fn smooth_bands(data: &mut [f32], rows: usize, cols: usize, taps: &[f32]) {
    smooth_step(data, None, rows, cols, taps, false);
}

/// The proxy's prior step in one pass per band: x ← clamp(G(x + step), 0, 1)
/// (no step and no clamp when `step` is `None` and `clamp` is false).
pub fn smooth_step(
    data: &mut [f32],
    step: Option<&[f32]>,
    rows: usize,
    cols: usize,
    taps: &[f32],
    clamp: bool,
) {
    let n = rows * cols;
    let simd = Simd::detect(false);
    match step {
        Some(st) => data.par_chunks_mut(n).zip(st.par_chunks(n)).for_each_init(
            Vec::new,
            |tmp, (band, add)| {
                smooth_band(
                    simd,
                    band,
                    None,
                    0,
                    Add::Band(add),
                    tmp,
                    rows,
                    cols,
                    taps,
                    clamp,
                )
            },
        ),
        None => data.par_chunks_mut(n).for_each_init(Vec::new, |tmp, band| {
            smooth_band(
                simd,
                band,
                None,
                0,
                Add::Nothing,
                tmp,
                rows,
                cols,
                taps,
                clamp,
            )
        }),
    }
}

/// One (rows × cols) frame smoothed, blocks of rows in parallel (one band
/// leaves [`smooth_bands`] a single thread); each block smooths the rows
/// its vertical taps read again, so the result is the same bits.
/// Every value of `out` (rows × cols) is written: it may hold anything.
pub fn smooth_frame_into(frame: &[f32], rows: usize, cols: usize, taps: &[f32], out: &mut [f32]) {
    let simd = Simd::detect(false);
    let block = 32;
    out.par_chunks_mut(block * cols)
        .enumerate()
        .for_each_init(Vec::new, |tmp, (i, dst)| {
            let src = Some(frame);
            smooth_band(
                simd,
                dst,
                src,
                i * block,
                Add::Nothing,
                tmp,
                rows,
                cols,
                taps,
                false,
            )
        });
}

/// [`smooth_step`] with step = Aᵀ `y`, each row of it computed as the prior
/// step reads it: the same result without writing and reading back a step
/// cube (at 660×714×28 each cube pass is 53 MB of memory traffic).
pub(crate) fn smooth_adjoint_step(
    data: &mut [f32],
    op: &CassiOperator,
    y: &[f32],
    taps: &[f32],
    clamp: bool,
) {
    let (_, rows, cols) = op.cube_shape();
    let simd = Simd::detect(false);
    data.par_chunks_mut(rows * cols)
        .enumerate()
        .for_each_init(Vec::new, |tmp, (k, band)| {
            let add = Add::Adjoint {
                op,
                y,
                band: k,
                simd,
            };
            smooth_band(simd, band, None, 0, add, tmp, rows, cols, taps, clamp)
        });
}

/// What one band's prior step adds before smoothing.
#[derive(Clone, Copy)]
enum Add<'a> {
    Nothing,
    /// The band of a step cube.
    Band(&'a [f32]),
    /// The band of Aᵀ y, row by row ([`CassiOperator::adjoint_row`]).
    Adjoint {
        op: &'a CassiOperator,
        y: &'a [f32],
        band: usize,
        simd: Simd,
    },
}

kernel!(smooth_band, smooth_band_port, smooth_band_avx,
    (band: &mut [f32], from: Option<&[f32]>, first: usize, add: Add<'_>, tmp: &mut Vec<f32>,
     rows: usize, cols: usize, taps: &[f32], clamp: bool) -> ()
    = smooth_band_body(band, from, first, add, tmp, rows, cols, taps, clamp));

/// One band: band ← clamp?(G(band + add)), in place (`from` `None`,
/// `first` 0), or the output rows `first`… of G(`from`) into `band`. Each
/// pass writes every output once from the symmetric tap pairs
/// (w₀·s[c] + Σⱼ wⱼ·(s[c−j] + s[c+j])): the profile had this step at 46 % of
/// a calibration when it accumulated one tap per sweep over the row. The
/// horizontal pass fills a ring of 2r + 1 rows just ahead of the vertical
/// one (a whole-band buffer, 1.9 MB at 660×714, did not stay in the core's
/// cache).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn smooth_band_body(
    band: &mut [f32],
    from: Option<&[f32]>,
    first: usize,
    add: Add<'_>,
    tmp: &mut Vec<f32>,
    rows: usize,
    cols: usize,
    taps: &[f32],
    clamp: bool,
) {
    let r = taps.len() / 2;
    // the tap weights from the centre outwards
    let w = &taps[r..];
    let ring = (2 * r + 1).min(rows);
    // a padded row (r edge-replicated values on each side), a step row and
    // the ring of horizontally smoothed rows
    tmp.resize(cols + 2 * r + cols + ring * cols, 0.0);
    let (src, tmp) = tmp.split_at_mut(cols + 2 * r);
    let (step_row, ring_rows) = tmp.split_at_mut(cols);
    let slot = |i: usize| (i % ring) * cols..(i % ring + 1) * cols;
    let mut next = first.saturating_sub(r);
    for row in first..first + band.len() / cols {
        // horizontal, up to the last row this output row reads
        while next <= (row + r).min(rows - 1) {
            let x = match from {
                Some(f) => &f[next * cols..(next + 1) * cols],
                None => &band[next * cols..(next + 1) * cols],
            };
            let inner = &mut src[r..r + cols];
            let a = match add {
                Add::Nothing => None,
                Add::Band(a) => Some(&a[next * cols..(next + 1) * cols]),
                Add::Adjoint {
                    op,
                    y,
                    band: k,
                    simd,
                } => {
                    op.adjoint_row(simd, y, k, next, step_row);
                    Some(&step_row[..])
                }
            };
            match a {
                Some(a) => {
                    for ((s, &xv), &av) in inner.iter_mut().zip(x).zip(a) {
                        *s = xv + av;
                    }
                }
                None => inner.copy_from_slice(x),
            }
            let (first, last) = (src[r], src[r + cols - 1]);
            src[..r].fill(first);
            src[r + cols..].fill(last);
            symmetric_pass(
                &mut ring_rows[slot(next)],
                |j| &src[r - j..r - j + cols],
                |j| &src[r + j..r + j + cols],
                w,
            );
            next += 1;
        }
        // vertical: whole rows, edge rows replicated
        let row_at = |i: isize| slot(i.clamp(0, rows as isize - 1) as usize);
        let dst = &mut band[(row - first) * cols..(row - first + 1) * cols];
        let ri = row as isize;
        symmetric_pass(
            dst,
            |j| &ring_rows[row_at(ri - j as isize)],
            |j| &ring_rows[row_at(ri + j as isize)],
            w,
        );
        if clamp {
            dst.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        }
    }
}

/// dst = w[0]·centre + Σ_{j≥1} w[j]·(before(j) + after(j)), elementwise;
/// `before(0)` is the centre. Radii 1–3 (σ ≤ 1) get one fused sweep.
#[inline(always)]
fn symmetric_pass<'a>(
    dst: &mut [f32],
    before: impl Fn(usize) -> &'a [f32],
    after: impl Fn(usize) -> &'a [f32],
    w: &[f32],
) {
    let n = dst.len();
    let c = &before(0)[..n];
    match w.len() {
        2 => {
            let (b1, a1) = (&before(1)[..n], &after(1)[..n]);
            for i in 0..n {
                dst[i] = w[0] * c[i] + w[1] * (b1[i] + a1[i]);
            }
        }
        3 => {
            let (b1, a1, b2, a2) = (
                &before(1)[..n],
                &after(1)[..n],
                &before(2)[..n],
                &after(2)[..n],
            );
            for i in 0..n {
                dst[i] = w[0] * c[i] + w[1] * (b1[i] + a1[i]) + w[2] * (b2[i] + a2[i]);
            }
        }
        4 => {
            let (b1, a1, b2, a2) = (
                &before(1)[..n],
                &after(1)[..n],
                &before(2)[..n],
                &after(2)[..n],
            );
            let (b3, a3) = (&before(3)[..n], &after(3)[..n]);
            for i in 0..n {
                dst[i] = w[0] * c[i]
                    + w[1] * (b1[i] + a1[i])
                    + w[2] * (b2[i] + a2[i])
                    + w[3] * (b3[i] + a3[i]);
            }
        }
        _ => {
            for (d, &v) in dst.iter_mut().zip(c) {
                *d = w[0] * v;
            }
            for (j, &wj) in w.iter().enumerate().skip(1) {
                for ((d, &b), &a) in dst.iter_mut().zip(before(j)).zip(after(j)) {
                    *d += wj * (b + a);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preserves_constants_and_mass_and_spreads_a_point() {
        let taps = gaussian_taps(0.7);
        assert!((taps.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        let mut c = vec![0.3f32; 2 * 9 * 11];
        smooth_bands(&mut c, 9, 11, &taps);
        assert!(c.iter().all(|v| (v - 0.3).abs() < 1e-6));
        let mut p = vec![0.0f32; 9 * 11];
        p[4 * 11 + 5] = 1.0;
        smooth_bands(&mut p, 9, 11, &taps);
        assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert!(p[4 * 11 + 5] < 0.5 && p[4 * 11 + 6] > 0.05 && p[5 * 11 + 5] > 0.05);
        assert!((p[4 * 11 + 6] - p[5 * 11 + 5]).abs() < 1e-6, "isotropic");
    }

    /// Against a direct edge-clamped 2-D convolution, for every radius
    /// the fused sweeps specialise (1–3) and the general one (4).
    #[test]
    fn equals_a_direct_clamped_convolution() {
        let mut rng = crate::Rng::new(9);
        let (rows, cols) = (11, 17);
        let x: Vec<f32> = (0..rows * cols).map(|_| rng.uniform() as f32).collect();
        for sigma in [0.3f32, 0.7, 1.0, 1.4] {
            let taps = gaussian_taps(sigma);
            let r = (taps.len() / 2) as isize;
            let at = |i: isize, j: isize| {
                x[i.clamp(0, rows as isize - 1) as usize * cols
                    + j.clamp(0, cols as isize - 1) as usize]
            };
            let mut got = x.clone();
            smooth_bands(&mut got, rows, cols, &taps);
            for i in 0..rows as isize {
                for j in 0..cols as isize {
                    let mut want = 0.0f64;
                    for (a, &wa) in taps.iter().enumerate() {
                        for (b, &wb) in taps.iter().enumerate() {
                            want += (wa * wb) as f64
                                * at(i + a as isize - r, j + b as isize - r) as f64;
                        }
                    }
                    let g = got[i as usize * cols + j as usize] as f64;
                    assert!(
                        (g - want).abs() < 1e-5,
                        "σ {sigma} ({i}, {j}): {g} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn every_compiled_copy_gives_the_portable_ones_bits() {
        let mut rng = crate::Rng::new(4);
        let (rows, cols) = (13, 37);
        let x: Vec<f32> = (0..rows * cols).map(|_| rng.uniform() as f32).collect();
        let add: Vec<f32> = (0..rows * cols)
            .map(|_| rng.uniform() as f32 - 0.5)
            .collect();
        let taps = gaussian_taps(1.0);
        let run = |simd: Simd| {
            let mut b = x.clone();
            smooth_band(
                simd,
                &mut b,
                None,
                0,
                Add::Band(&add),
                &mut Vec::new(),
                rows,
                cols,
                &taps,
                true,
            );
            b
        };
        for simd in Simd::available() {
            assert_eq!(run(Simd::Portable), run(simd), "{simd:?}");
        }
    }

    /// The fused step gives the bits of the adjoint followed by the smoothing,
    /// for both dispersion models, and with fewer rows than the ring.
    #[test]
    fn the_adjoint_step_equals_adjoint_then_smoothing() {
        use crate::linop::LinearOperator;
        use crate::optics::{Dispersion, DispersionModel};
        use crate::params::DispersionParams;
        let mut rng = crate::Rng::new(7);
        for (rows, cols, sigma) in [(13, 29, 0.7f32), (4, 9, 1.0)] {
            for model in [DispersionModel::Rounded, DispersionModel::Subpixel] {
                let params = DispersionParams {
                    a1: 2.3,
                    alpha_deg: 9.0,
                    a2: 0.0,
                };
                let d = Dispersion::new(5, params, model).unwrap();
                let mask: Vec<f32> = (0..rows * cols).map(|_| rng.uniform() as f32).collect();
                let mask = crate::cube::Frame::from_vec(rows, cols, mask).unwrap();
                let op = CassiOperator::new(mask, d).unwrap();
                let y: Vec<f32> = (0..op.range_len())
                    .map(|_| rng.uniform() as f32 - 0.5)
                    .collect();
                let x: Vec<f32> = (0..op.domain_len()).map(|_| rng.uniform() as f32).collect();
                let taps = gaussian_taps(sigma);
                let mut step = vec![0.0; op.domain_len()];
                op.adjoint(&y, &mut step);
                let mut want = x.clone();
                smooth_step(&mut want, Some(&step), rows, cols, &taps, true);
                let mut got = x.clone();
                smooth_adjoint_step(&mut got, &op, &y, &taps, true);
                assert_eq!(got, want, "{model:?} {rows}×{cols}");
            }
        }
    }

    /// Row blocks in parallel give the bits of the whole-frame smoothing,
    /// with a last block shorter than the rest and a radius past a block.
    #[test]
    fn the_frame_in_row_blocks_equals_the_whole_frame() {
        let mut rng = crate::Rng::new(3);
        for (rows, sigma) in [(75, 2.0f32), (33, 12.0), (5, 0.7)] {
            let cols = 19;
            let x: Vec<f32> = (0..rows * cols).map(|_| rng.uniform() as f32).collect();
            let taps = gaussian_taps(sigma);
            let mut want = x.clone();
            smooth_bands(&mut want, rows, cols, &taps);
            // a reused buffer: whatever it held is overwritten
            let mut got = vec![f32::NAN; rows * cols];
            smooth_frame_into(&x, rows, cols, &taps, &mut got);
            assert_eq!(got, want, "{rows} rows, σ {sigma}");
        }
    }
}
