//! A coarse scene: the cube as a smooth function of few coefficients,
//! bilinear in space between nodes every `cell_px` pixels and piecewise
//! linear in wavelength between `spectral_nodes` evenly spaced bands. The
//! scene fit (`scene_fit.rs`) solves for these coefficients for every
//! candidate instrument; the basis is smooth on the scale of the mask's
//! code, so it cannot imitate a misplaced code, only the scene's slow
//! variation and spectrum.
//!
//! As a [`LinearOperator`] U: coefficients (spectral nodes × node rows ×
//! node cols) → cube (bands × rows × cols); its adjoint is tested.
//!
//! With a detail map d ([`CoarseScene::with_detail`], the scene fit's
//! detail pass) every band's smooth image is multiplied by d pixel by
//! pixel: x_k = d ⊙ (U z)_k, still linear in z, the smooth factor carrying
//! each region's spectrum and d the texture the nodes are too far apart for.
//! With G maps (spectral groups of consecutive bands) band k takes map
//! ⌊k·G/bands⌋: a texture of colour, not of brightness alone.

use rayon::prelude::*;

use crate::linop::LinearOperator;
use crate::optics::operator::CubeRows;
use crate::simd::{Simd, kernel};

/// The basis of one cube shape.
#[derive(Debug, Clone)]
pub(crate) struct CoarseScene {
    bands: usize,
    rows: usize,
    cols: usize,
    spectral_nodes: usize,
    node_rows: usize,
    node_cols: usize,
    /// Per pixel row / col: the node before it and the weight of the one after.
    row_taps: Vec<(usize, f32)>,
    /// Node spacing, pixels, and the weight of the next node at each
    /// offset 0 … cell − 1 within a cell.
    cell: usize,
    fractions: Vec<f32>,
    /// Per band: its spectral nodes and their weights (two, between
    /// evenly spaced nodes; every one, in a basis of given spectra).
    band_taps: Vec<Vec<(usize, f32)>>,
    /// In a basis of given spectra ([`CoarseScene::with_spectra`]): their
    /// least-squares projector (nodes × bands), which [`Self::nodes_of`]
    /// takes a cube's spectra through; `None`: evenly spaced nodes.
    projector: Option<Vec<f64>>,
    /// Per map and pixel (maps × rows × cols): the factor a band's pixels
    /// are multiplied by, band k by map ⌊k·maps/bands⌋ (`None`: 1).
    detail: Option<Vec<f32>>,
    /// Per band: its detail map's offset in `detail`.
    detail_offsets: Vec<usize>,
    simd: Simd,
}

thread_local! {
    /// Per-band coarse images (bands × node rows × node cols).
    static COARSE_BANDS: std::cell::RefCell<Vec<f32>> = std::cell::RefCell::default();
}

/// Nodes every `cell` pixels over `n` pixels: the node before each pixel
/// and the weight of the node after it.
fn taps(n: usize, cell: usize) -> (usize, Vec<(usize, f32)>) {
    let nodes = (n.saturating_sub(1)).div_ceil(cell) + 1;
    let t = (0..n)
        .map(|i| (i / cell, (i % cell) as f32 / cell as f32))
        .collect();
    (nodes, t)
}

/// `row` ← the node values `line` interpolated linearly over cells of `C`
/// pixels (the last node held past the edge).
#[inline]
fn expand_cells<const C: usize>(line: &[f32], row: &mut [f32]) {
    let frac: [f32; C] = std::array::from_fn(|j| j as f32 / C as f32);
    let nc = line.len();
    let c = row.len() / C;
    let mut chunks = row.chunks_exact_mut(C);
    for (c, chunk) in (&mut chunks).enumerate() {
        let a = line[c];
        let d = if c + 1 < nc { line[c + 1] - a } else { 0.0 };
        for j in 0..C {
            chunk[j] = a + frac[j] * d;
        }
    }
    let rest = chunks.into_remainder();
    if !rest.is_empty() {
        let a = line[c];
        let d = if c + 1 < nc { line[c + 1] - a } else { 0.0 };
        for (j, o) in rest.iter_mut().enumerate() {
            *o = a + frac[j] * d;
        }
    }
}

/// `row` ← the node values `line` interpolated linearly over cells of
/// `cell` pixels (the last node held past the edge): the scene fit's
/// widths, 4 and 8, through the compiled copy `simd` picks, others pixel
/// by pixel.
#[inline]
fn expand_row(simd: Simd, cell: usize, fractions: &[f32], line: &[f32], row: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if simd.has_avx() && (cell == 4 || cell == 8) {
        // SAFETY: `Simd::detect` answers a copy with AVX only when it found
        // AVX at run time (tests pass the copies `Simd::available` lists).
        unsafe {
            if cell == 4 {
                expand_cells_avx::<4>(line, row)
            } else {
                expand_cells_avx::<8>(line, row)
            }
        }
        return;
    }
    let _ = simd;
    match cell {
        4 => expand_cells::<4>(line, row),
        8 => expand_cells::<8>(line, row),
        _ => {
            let nc = line.len();
            for (c, chunk) in row.chunks_mut(cell).enumerate() {
                let a = line[c];
                let d = if c + 1 < nc { line[c + 1] - a } else { 0.0 };
                chunk
                    .iter_mut()
                    .zip(fractions)
                    .for_each(|(o, &f)| *o = a + f * d);
            }
        }
    }
}

/// [`expand_cells`] with AVX, the same bits (a + f·d lane by lane):
/// 8-lane vectors of one 8-pixel cell or two 4-pixel ones, written out
/// (the compiler's own AVX copy of `expand_cells` interleaved the cells
/// through shuffles and was slower than the baseline's SSE).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline(never)]
unsafe fn expand_cells_avx<const C: usize>(line: &[f32], row: &mut [f32]) {
    use std::arch::x86_64::{
        _mm_set1_ps, _mm256_add_ps, _mm256_loadu_ps, _mm256_mul_ps, _mm256_set_m128,
        _mm256_set1_ps, _mm256_storeu_ps,
    };
    const { assert!(C == 4 || C == 8) };
    let frac: [f32; 8] = std::array::from_fn(|j| (j % C) as f32 / C as f32);
    let nc = line.len();
    let slope = |c: usize| {
        if c + 1 < nc {
            line[c + 1] - line[c]
        } else {
            0.0
        }
    };
    // whole vectors: 8 pixels, of cells c0 and c0 + 1 (C = 4) or c0 (C = 8)
    let vectors = row.len() / 8;
    // SAFETY: `frac` holds 8 floats.
    let fr = unsafe { _mm256_loadu_ps(frac.as_ptr()) };
    for (v, out) in row.chunks_exact_mut(8).enumerate() {
        let (a, d) = if C == 8 {
            (_mm256_set1_ps(line[v]), _mm256_set1_ps(slope(v)))
        } else {
            let (c0, c1) = (2 * v, 2 * v + 1);
            (
                _mm256_set_m128(_mm_set1_ps(line[c1]), _mm_set1_ps(line[c0])),
                _mm256_set_m128(_mm_set1_ps(slope(c1)), _mm_set1_ps(slope(c0))),
            )
        };
        // SAFETY: `out` holds 8 floats.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), _mm256_add_ps(a, _mm256_mul_ps(fr, d))) };
    }
    // the last pixels, one by one
    for (p, o) in row.iter_mut().enumerate().skip(8 * vectors) {
        let c = p / C;
        *o = line[c] + frac[p % C] * slope(c);
    }
}

/// Adds the adjoint of a smooth row (cells of `cell` pixels, the next
/// node's weight `fractions[j]` at offset j, the last node held past the
/// edge) to the two node rows around it: `into.0` += (1 − f)·line,
/// `into.1` += f·line (`into.1` empty when f = 0). `row` is first
/// multiplied by `detail` in place (when not empty); `line` holds
/// node cols + 2 · cells. Each cell's sums run pixel by pixel in order
/// from 0, so every compiled copy gives the bits of accumulating cell by
/// cell into a zeroed line.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn add_down_row_body(
    row: &mut [f32],
    detail: &[f32],
    cell: usize,
    fractions: &[f32],
    line: &mut [f32],
    into: (&mut [f32], &mut [f32]),
    f: f32,
) {
    if !detail.is_empty() {
        row.iter_mut().zip(detail).for_each(|(v, &d)| *v *= d);
    }
    let nc = into.0.len();
    let cells = row.len().div_ceil(cell);
    let (line, moments) = line.split_at_mut(nc);
    let (sums, nexts) = moments[..2 * cells].split_at_mut(cells);
    let full = row.len() / cell;
    // fixed-width cells (the scene fit's) one cell per lane: the compiler
    // vectorises across cells without reordering any cell's sum
    match cell {
        4 => cell_moments_fixed::<4>(&row[..4 * full], &mut sums[..full], &mut nexts[..full]),
        8 => cell_moments_fixed::<8>(&row[..8 * full], &mut sums[..full], &mut nexts[..full]),
        _ => cell_moments_any(&row[..cell * full], cell, fractions, sums, nexts),
    }
    if full < cells {
        cell_moments_any(
            &row[cell * full..],
            cell,
            fractions,
            &mut sums[full..],
            &mut nexts[full..],
        );
    }
    // node c takes (0 + next[c − 1]) + (sum[c] − next[c]): cell c − 1's
    // share first, as the cell-by-cell accumulation adds them (nc is cells
    // or cells + 1: the last cell's share is dropped past the last node)
    if cells > 0 {
        line[0] = 0.0 + (sums[0] - nexts[0]);
        let inner = &mut line[1..cells];
        for (c, l) in inner.iter_mut().enumerate() {
            *l = (0.0 + nexts[c]) + (sums[c + 1] - nexts[c + 1]);
        }
        if nc > cells {
            line[cells] = 0.0 + nexts[cells - 1];
        }
    }
    let (now, next) = into;
    now.iter_mut()
        .zip(line.iter())
        .for_each(|(c, &l)| *c += l - f * l);
    next.iter_mut()
        .zip(line.iter())
        .for_each(|(c, &l)| *c += f * l);
}

/// Each cell's pixel sum and fraction-weighted sum, pixel by pixel.
#[inline(always)]
fn cell_moments_any(
    row: &[f32],
    cell: usize,
    fractions: &[f32],
    sums: &mut [f32],
    nexts: &mut [f32],
) {
    for ((chunk, s), n) in row.chunks(cell).zip(sums.iter_mut()).zip(nexts.iter_mut()) {
        let (mut sum, mut next) = (0.0f32, 0.0f32);
        for (&v, &f) in chunk.iter().zip(fractions) {
            sum += v;
            next += f * v;
        }
        (*s, *n) = (sum, next);
    }
}

/// [`cell_moments_any`] of the full cells of `C` pixels of `row`, one cell
/// per lane.
#[inline(always)]
fn cell_moments_fixed<const C: usize>(row: &[f32], sums: &mut [f32], nexts: &mut [f32]) {
    let frac: [f32; C] = std::array::from_fn(|j| j as f32 / C as f32);
    let n = sums.len();
    let (row, nexts) = (&row[..C * n], &mut nexts[..n]);
    for c in 0..n {
        let (mut sum, mut next) = (0.0f32, 0.0f32);
        for j in 0..C {
            let v = row[C * c + j];
            sum += v;
            next += frac[j] * v;
        }
        sums[c] = sum;
        nexts[c] = next;
    }
}

kernel!(add_down_row_kernel, add_down_row_port, add_down_row_avx,
    (row: &mut [f32], detail: &[f32], cell: usize, fractions: &[f32], line: &mut [f32],
     into: (&mut [f32], &mut [f32]), f: f32) -> ()
    = add_down_row_body(row, detail, cell, fractions, line, into, f));

impl CoarseScene {
    /// The basis for `bands × rows × cols` cubes; `spectral_nodes` is
    /// clamped to 2 … bands (bands: every band free).
    pub(crate) fn new(
        bands: usize,
        rows: usize,
        cols: usize,
        cell_px: usize,
        spectral_nodes: usize,
    ) -> Self {
        let cell = cell_px.max(1);
        let (node_rows, row_taps) = taps(rows, cell);
        let (node_cols, _) = taps(cols, cell);
        let fractions = (0..cell).map(|j| j as f32 / cell as f32).collect();
        let spectral_nodes = spectral_nodes.clamp(2.min(bands), bands);
        let band_taps = (0..bands)
            .map(|k| {
                if spectral_nodes == bands || bands < 2 {
                    return vec![(k, 1.0)];
                }
                let t = k as f64 * (spectral_nodes - 1) as f64 / (bands - 1) as f64;
                let j = (t.floor() as usize).min(spectral_nodes - 2);
                let f = (t - j as f64) as f32;
                vec![(j, 1.0 - f), (j + 1, f)]
            })
            .collect();
        Self {
            bands,
            rows,
            cols,
            spectral_nodes,
            node_rows,
            node_cols,
            row_taps,
            cell,
            fractions,
            band_taps,
            projector: None,
            detail: None,
            detail_offsets: Vec::new(),
            simd: Simd::detect(false),
        }
    }

    /// The basis with every band's pixels multiplied by a detail map:
    /// `detail` holds G maps (G × rows × cols, row-major, G ≥ 1 dividing
    /// its length), band k taking map ⌊k·G/bands⌋.
    pub(crate) fn with_detail(mut self, detail: Vec<f32>) -> Self {
        let plane = self.rows * self.cols;
        let maps = detail.len() / plane.max(1);
        assert!(
            maps >= 1 && maps * plane == detail.len() && maps <= self.bands.max(1),
            "CoarseScene::with_detail: {} factors for {plane} pixels and {} bands",
            detail.len(),
            self.bands
        );
        self.detail_offsets = (0..self.bands)
            .map(|k| k * maps / self.bands * plane)
            .collect();
        self.detail = Some(detail);
        self
    }

    /// The basis with its spectra spanned by the columns of `spectra`
    /// (bands × m, row-major, linearly independent) in place of evenly
    /// spaced nodes: band k of node j's image weighs `spectra[k·m + j]`.
    pub(crate) fn with_spectra(mut self, spectra: &[f64], m: usize) -> Self {
        let bands = self.bands;
        assert!(
            m >= 1 && spectra.len() == bands * m,
            "CoarseScene::with_spectra: {} values for {bands} bands × {m}",
            spectra.len()
        );
        self.spectral_nodes = m;
        self.band_taps = (0..bands)
            .map(|k| (0..m).map(|j| (j, spectra[k * m + j] as f32)).collect())
            .collect();
        self.projector = Some(super::spectral_basis::projector(spectra, bands, m));
        self
    }

    /// The basis running the given compiled copy of its row kernels.
    #[cfg(test)]
    fn with_simd(mut self, simd: Simd) -> Self {
        self.simd = simd;
        self
    }

    /// Row `i` of band `k`'s detail map, if any.
    #[inline]
    fn detail_row(&self, k: usize, i: usize) -> Option<&[f32]> {
        self.detail.as_deref().map(|d| {
            let at = self.detail_offsets[k] + i * self.cols;
            &d[at..at + self.cols]
        })
    }

    fn plane(&self) -> usize {
        self.node_rows * self.node_cols
    }

    /// Band `k`'s coarse image (node rows × node cols) → its pixels.
    fn up_band(&self, k: usize, coarse: &[f32], out: &mut [f32], line: &mut Vec<f32>) {
        for (i, row) in out.chunks_mut(self.cols).enumerate() {
            self.up_row(k, coarse, i, row, line);
        }
    }

    /// Pixel row `i` of band `k`'s coarse image, times its detail map.
    #[inline]
    fn up_row(&self, k: usize, coarse: &[f32], i: usize, row: &mut [f32], line: &mut Vec<f32>) {
        let nc = self.node_cols;
        line.resize(nc, 0.0);
        let (q, f) = self.row_taps[i];
        let a = &coarse[q * nc..(q + 1) * nc];
        if f == 0.0 {
            line.copy_from_slice(a);
        } else {
            let b = &coarse[(q + 1) * nc..(q + 2) * nc];
            line.iter_mut()
                .zip(a.iter().zip(b))
                .for_each(|(l, (&a, &b))| *l = a + f * (b - a));
        }
        expand_row(self.simd, self.cell, &self.fractions, line, row);
        if let Some(d) = self.detail_row(k, i) {
            row.iter_mut().zip(d).for_each(|(o, &d)| *o *= d);
        }
    }

    /// The adjoint of [`Self::up_band`]: band `k`'s pixels → its coarse
    /// image (`buf`: a row's scratch).
    fn down_band(
        &self,
        k: usize,
        band: &[f32],
        coarse: &mut [f32],
        line: &mut Vec<f32>,
        buf: &mut Vec<f32>,
    ) {
        coarse.fill(0.0);
        for (i, row) in band.chunks(self.cols).enumerate() {
            buf.clear();
            buf.extend_from_slice(row);
            self.add_down_row(k, buf, i, coarse, line);
        }
    }

    /// Adds the adjoint of [`Self::up_row`] of band `k`'s pixel row `i` to
    /// `coarse` (`row` is overwritten: the detail map is applied in place;
    /// `line`: scratch).
    #[inline]
    fn add_down_row(
        &self,
        k: usize,
        row: &mut [f32],
        i: usize,
        coarse: &mut [f32],
        line: &mut Vec<f32>,
    ) {
        let nc = self.node_cols;
        line.resize(nc + 2 * row.len().div_ceil(self.cell), 0.0);
        let (q, f) = self.row_taps[i];
        let (now, next) = coarse[q * nc..].split_at_mut(nc);
        let next = if f != 0.0 {
            &mut next[..nc]
        } else {
            &mut [][..]
        };
        add_down_row_kernel(
            self.simd,
            row,
            self.detail_row(k, i).unwrap_or(&[]),
            self.cell,
            &self.fractions,
            line,
            (now, next),
            f,
        );
    }

    /// Band `k`'s coarse image from the coefficients `z` (the spectral
    /// interpolation).
    fn band_image(&self, z: &[f32], k: usize, coarse: &mut [f32]) {
        let plane = self.plane();
        coarse.fill(0.0);
        for &(j, w) in self.band_taps[k].iter().filter(|t| t.1 != 0.0) {
            coarse
                .iter_mut()
                .zip(&z[j * plane..(j + 1) * plane])
                .for_each(|(c, &v)| *c += w * v);
        }
    }

    /// The adjoint of [`Self::band_image`] over every band: the bands'
    /// coarse images (bands × plane) → coefficients.
    fn nodes_from_band_images(&self, images: &[f32], z: &mut [f32]) {
        let plane = self.plane();
        z.par_chunks_mut(plane).enumerate().for_each(|(j, out)| {
            out.fill(0.0);
            for (k, taps) in self.band_taps.iter().enumerate() {
                for &(node, w) in taps {
                    if node == j && w != 0.0 {
                        out.iter_mut()
                            .zip(&images[k * plane..(k + 1) * plane])
                            .for_each(|(o, &v)| *o += w * v);
                    }
                }
            }
        });
    }

    /// Every band's coarse image (bands × plane) from `z`.
    pub(crate) fn band_images(&self, z: &[f32], images: &mut Vec<f32>) {
        let plane = self.plane();
        images.resize(self.bands * plane, 0.0);
        images
            .par_chunks_mut(plane)
            .enumerate()
            .for_each(|(k, out)| self.band_image(z, k, out));
    }

    /// Uᵀ of a cube given row by row: `row(k, r, buf)` writes row `r` of
    /// band `k` into `buf` (cols long; overwritten afterwards); `images` is
    /// scratch (bands × plane). Bands in parallel.
    pub(crate) fn adjoint_rows(
        &self,
        row: impl Fn(usize, usize, &mut [f32]) + Sync,
        images: &mut Vec<f32>,
        z: &mut [f32],
    ) {
        let plane = self.plane();
        images.resize(self.bands * plane, 0.0);
        images.par_chunks_mut(plane).enumerate().for_each_init(
            || (vec![0.0f32; self.cols], Vec::new()),
            |(buf, line), (k, coarse)| {
                coarse.fill(0.0);
                for i in 0..self.rows {
                    row(k, i, buf);
                    self.add_down_row(k, buf, i, coarse, line);
                }
            },
        );
        self.nodes_from_band_images(images, z);
    }
}

/// U z one row at a time, from the bands' coarse images
/// ([`CoarseScene::band_images`]): for products that read the cube once
/// per row ([`CassiOperator::apply_rows`]), without storing it.
pub(crate) struct CoarseRows<'a> {
    pub basis: &'a CoarseScene,
    pub images: &'a [f32],
}

/// A thread's buffers for [`CoarseRows`]: the last row made and which
/// (band, row) it is (a band's taps read the same row in turn).
#[derive(Default)]
pub(crate) struct RowScratch {
    line: Vec<f32>,
    row: Vec<f32>,
    made: Option<(usize, usize)>,
}

impl CubeRows for CoarseRows<'_> {
    type Scratch = RowScratch;
    #[inline]
    fn row<'s>(&'s self, k: usize, r: usize, scratch: &'s mut RowScratch) -> &'s [f32] {
        if scratch.made != Some((k, r)) {
            let b = self.basis;
            scratch.row.resize(b.cols, 0.0);
            let plane = b.plane();
            let image = &self.images[k * plane..(k + 1) * plane];
            b.up_row(k, image, r, &mut scratch.row, &mut scratch.line);
            scratch.made = Some((k, r));
        }
        &scratch.row
    }
}

impl CoarseScene {
    /// The coefficients that put `cube`'s own values on every node: node
    /// (j, q, p) takes the cube at pixel (q·cell, p·cell) — the last pixel
    /// for a node past the edge — linearly between the two bands around
    /// spectral position j·(bands − 1)/(nodes − 1). U of them is the
    /// cube's coarse interpolant.
    pub(crate) fn nodes_of(&self, cube: &[f32]) -> Vec<f32> {
        let (bands, rows, cols) = (self.bands, self.rows, self.cols);
        let plane = self.plane();
        let mut z = vec![0.0f32; self.domain_len()];
        let pixel = |q: usize, p: usize| {
            let r = (q * self.cell).min(rows - 1);
            let c = (p * self.cell).min(cols - 1);
            r * cols + c
        };
        if let Some(projector) = &self.projector {
            // each node's spectrum projected onto the basis' spectra
            let m = self.spectral_nodes;
            for q in 0..self.node_rows {
                for p in 0..self.node_cols {
                    let at = pixel(q, p);
                    for j in 0..m {
                        let v: f64 = (0..bands)
                            .map(|k| projector[j * bands + k] * cube[k * rows * cols + at] as f64)
                            .sum();
                        z[j * plane + q * self.node_cols + p] = v as f32;
                    }
                }
            }
            return z;
        }
        for (j, out) in z.chunks_mut(plane).enumerate() {
            let (k0, k1, f) = if self.spectral_nodes == bands || bands < 2 {
                (j, j, 0.0)
            } else {
                let t = j as f64 * (bands - 1) as f64 / (self.spectral_nodes - 1) as f64;
                let k0 = (t.floor() as usize).min(bands - 1);
                (k0, (k0 + 1).min(bands - 1), (t - k0 as f64) as f32)
            };
            for (q, row) in out.chunks_mut(self.node_cols).enumerate() {
                for (p, o) in row.iter_mut().enumerate() {
                    let at = pixel(q, p);
                    let (a, b) = (cube[k0 * rows * cols + at], cube[k1 * rows * cols + at]);
                    *o = a + f * (b - a);
                }
            }
        }
        z
    }
}

impl LinearOperator for CoarseScene {
    fn domain_len(&self) -> usize {
        self.spectral_nodes * self.plane()
    }

    fn range_len(&self) -> usize {
        self.bands * self.rows * self.cols
    }

    fn apply(&self, x: &[f32], y: &mut [f32]) {
        let plane = self.plane();
        y.par_chunks_mut(self.rows * self.cols)
            .enumerate()
            .for_each_init(
                || (vec![0.0f32; plane], Vec::new()),
                |(coarse, line), (k, band)| {
                    self.band_image(x, k, coarse);
                    self.up_band(k, coarse, band, line);
                },
            );
    }

    fn adjoint(&self, y: &[f32], x: &mut [f32]) {
        let plane = self.plane();
        crate::scratch::with_taken(&COARSE_BANDS, |coarse| {
            coarse.resize(self.bands * plane, 0.0);
            coarse
                .par_chunks_mut(plane)
                .zip(y.par_chunks(self.rows * self.cols))
                .enumerate()
                .for_each_init(
                    || (Vec::new(), Vec::new()),
                    |(line, buf), (k, (c, band))| self.down_band(k, band, c, line, buf),
                );
            self.nodes_from_band_images(coarse, x);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linop::adjoint_mismatch;

    /// Exact adjoint for cells that do and do not divide the size, with
    /// spectral nodes and with every band free.
    #[test]
    fn the_adjoint_is_exact() {
        for (bands, rows, cols, cell, nodes) in
            [(7, 20, 23, 4, 3), (5, 16, 16, 8, 5), (28, 17, 9, 3, 10)]
        {
            let u = CoarseScene::new(bands, rows, cols, cell, nodes);
            let e = adjoint_mismatch(&u, 7);
            assert!(e < 1e-5, "{bands}×{rows}×{cols} cell {cell}: {e}");
        }
    }

    /// The adjoint stays exact with one detail map or several, and band
    /// k's map (⌊k·G/bands⌋ of G) multiplies its smooth image pixel by
    /// pixel; the row-by-row product agrees.
    #[test]
    fn a_detail_map_multiplies_every_band() {
        let (bands, rows, cols) = (6, 19, 14);
        let plane = rows * cols;
        for maps in [1, 3] {
            let detail: Vec<f32> = (0..maps * plane)
                .map(|i| 0.5 + ((i * 29) % 13) as f32 / 13.0)
                .collect();
            let plain = CoarseScene::new(bands, rows, cols, 4, 3);
            let u = plain.clone().with_detail(detail.clone());
            let e = adjoint_mismatch(&u, 11);
            assert!(e < 1e-5, "adjoint with {maps} detail maps: {e}");
            let z: Vec<f32> = (0..u.domain_len())
                .map(|i| 0.2 + ((i * 7) % 5) as f32 / 5.0)
                .collect();
            let (mut smooth, mut detailed) =
                (vec![0.0f32; u.range_len()], vec![0.0f32; u.range_len()]);
            plain.apply(&z, &mut smooth);
            u.apply(&z, &mut detailed);
            for (k, (s, d)) in smooth.chunks(plane).zip(detailed.chunks(plane)).enumerate() {
                // bands 0–1 take map 0, 2–3 map 1, 4–5 map 2 (of three)
                let map = &detail[(k * maps / bands) * plane..][..plane];
                for ((&s, &d), &g) in s.iter().zip(d).zip(map) {
                    assert!((s * g - d).abs() < 1e-6, "band {k}: {s} × {g} ≠ {d}");
                }
            }
            let mut images = Vec::new();
            u.band_images(&z, &mut images);
            let rows_of = CoarseRows {
                basis: &u,
                images: &images,
            };
            let mut scratch = RowScratch::default();
            for k in 0..bands {
                for r in 0..rows {
                    let got = rows_of.row(k, r, &mut scratch).to_vec();
                    let want = &detailed[(k * rows + r) * cols..][..cols];
                    assert_eq!(got, want, "{maps} maps: band {k} row {r}");
                }
            }
        }
    }

    /// Every compiled copy of the row kernels (AVX, AVX-512) gives the portable copies' bits,
    /// forward and adjoint, with and without a detail map, for the fixed
    /// cell widths and another, on rows that are not whole vectors.
    #[test]
    fn every_compiled_copy_gives_the_portable_ones_bits() {
        let mut rng = crate::Rng::new(12);
        for (bands, rows, cols, cell, nodes) in [
            (6, 13, 37, 4, 3),
            (5, 11, 45, 8, 5),
            (4, 9, 29, 3, 4),
            (3, 8, 64, 8, 3),
        ] {
            let plane = rows * cols;
            let detail: Vec<f32> = (0..2 * plane).map(|_| rng.uniform() as f32 + 0.5).collect();
            let z: Vec<f32> = (0..CoarseScene::new(bands, rows, cols, cell, nodes).domain_len())
                .map(|_| rng.uniform() as f32 - 0.3)
                .collect();
            let y: Vec<f32> = (0..bands * plane)
                .map(|_| rng.uniform() as f32 - 0.4)
                .collect();
            for with_detail in [false, true] {
                let run = |simd: Simd| {
                    let mut u = CoarseScene::new(bands, rows, cols, cell, nodes).with_simd(simd);
                    if with_detail {
                        u = u.with_detail(detail.clone());
                    }
                    let mut cube = vec![0.0f32; u.range_len()];
                    u.apply(&z, &mut cube);
                    let mut back = vec![0.0f32; u.domain_len()];
                    u.adjoint(&y, &mut back);
                    (cube, back)
                };
                let port = run(Simd::Portable);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                for simd in Simd::available() {
                    let wide = run(simd);
                    let case = format!(
                        "{bands}×{rows}×{cols} cell {cell}, detail {with_detail}, {simd:?}"
                    );
                    assert_eq!(bits(&port.0), bits(&wide.0), "forward, {case}");
                    assert_eq!(bits(&port.1), bits(&wide.1), "adjoint, {case}");
                }
            }
        }
    }

    /// The adjoint's row, either compiled copy, gives the bits of adding
    /// cell by cell into a zeroed line (the loop it replaced, kept here as
    /// the reference): estimates made before the kernels stay reproducible.
    #[test]
    fn the_adjoint_row_gives_the_bits_of_the_cell_by_cell_loop() {
        let reference =
            |u: &CoarseScene, k: usize, row: &mut [f32], i: usize, coarse: &mut [f32]| {
                if let Some(d) = u.detail_row(k, i) {
                    row.iter_mut().zip(d).for_each(|(v, &d)| *v *= d);
                }
                let nc = u.node_cols;
                let mut line = vec![0.0f32; nc];
                for (c, chunk) in row.chunks(u.cell).enumerate() {
                    let (mut sum, mut next) = (0.0f32, 0.0f32);
                    for (&v, &f) in chunk.iter().zip(&u.fractions) {
                        sum += v;
                        next += f * v;
                    }
                    line[c] += sum - next;
                    if c + 1 < nc {
                        line[c + 1] += next;
                    }
                }
                let (q, f) = u.row_taps[i];
                coarse[q * nc..(q + 1) * nc]
                    .iter_mut()
                    .zip(&line)
                    .for_each(|(c, &l)| *c += l - f * l);
                if f != 0.0 {
                    coarse[(q + 1) * nc..(q + 2) * nc]
                        .iter_mut()
                        .zip(&line)
                        .for_each(|(c, &l)| *c += f * l);
                }
            };
        let mut rng = crate::Rng::new(21);
        for (bands, rows, cols, cell) in
            [(2, 9, 37, 4), (2, 17, 45, 8), (2, 9, 29, 3), (2, 9, 33, 4)]
        {
            let plane = rows * cols;
            let detail: Vec<f32> = (0..plane).map(|_| rng.uniform() as f32 + 0.5).collect();
            for simd in Simd::available() {
                let u = CoarseScene::new(bands, rows, cols, cell, 2)
                    .with_simd(simd)
                    .with_detail(detail.clone());
                let (mut got, mut want) = (vec![0.0f32; u.plane()], vec![0.0f32; u.plane()]);
                let mut line = Vec::new();
                for i in 0..rows {
                    let row: Vec<f32> = (0..cols).map(|_| rng.uniform() as f32 - 0.3).collect();
                    u.add_down_row(1, &mut row.clone(), i, &mut got, &mut line);
                    reference(&u, 1, &mut row.clone(), i, &mut want);
                }
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&got),
                    bits(&want),
                    "{cols} cols, cell {cell}, {simd:?}"
                );
            }
        }
    }

    /// Constant coefficients make a constant cube (the weights are a
    /// partition of unity in space and wavelength); a node's coefficient
    /// lands on its own pixel and band with weight 1 and fades linearly to
    /// the next node.
    #[test]
    fn interpolates_between_nodes() {
        let (bands, rows, cols) = (9, 17, 13);
        let u = CoarseScene::new(bands, rows, cols, 4, 5);
        let mut x = vec![0.7f32; u.domain_len()];
        let mut cube = vec![0.0f32; u.range_len()];
        u.apply(&x, &mut cube);
        assert!(cube.iter().all(|&v| (v - 0.7).abs() < 1e-6));
        // node (spectral 1, row 1, col 2) = band 2, pixel (4, 8)
        x.fill(0.0);
        let plane = u.plane();
        x[plane + u.node_cols + 2] = 1.0;
        u.apply(&x, &mut cube);
        let at = |k: usize, r: usize, c: usize| cube[(k * rows + r) * cols + c];
        assert!((at(2, 4, 8) - 1.0).abs() < 1e-6);
        assert!((at(2, 4, 10) - 0.5).abs() < 1e-6);
        assert!((at(3, 4, 8) - 0.5).abs() < 1e-6);
        assert!((at(2, 6, 6) - 0.25).abs() < 1e-6);
        assert_eq!(at(2, 4, 12), 0.0);
        assert_eq!(at(5, 4, 8), 0.0);
    }

    /// A cube the basis holds is its own coarse interpolant.
    #[test]
    fn a_cube_in_the_basis_is_its_own_nodes_interpolant() {
        let (bands, rows, cols) = (9, 17, 13);
        let u = CoarseScene::new(bands, rows, cols, 4, 5);
        let z: Vec<f32> = (0..u.domain_len())
            .map(|i| ((i * 37) % 11) as f32 / 11.0)
            .collect();
        let mut cube = vec![0.0f32; u.range_len()];
        u.apply(&z, &mut cube);
        let mut again = vec![0.0f32; u.range_len()];
        u.apply(&u.nodes_of(&cube), &mut again);
        // (every node on a pixel here: 17 = 4·4 + 1 rows, 13 = 3·4 + 1 cols)
        let worst = cube
            .iter()
            .zip(&again)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "{worst}");
    }

    /// In a basis of given spectra (three, not orthogonal) the adjoint is
    /// exact, band k of a node's image weighs the spectra's row k, and a
    /// cube the basis holds is its own projection (`nodes_of`).
    #[test]
    fn a_basis_of_given_spectra_has_an_exact_adjoint_and_projects_its_own_cubes() {
        let (bands, rows, cols, m) = (9, 17, 13, 3);
        let spectra: Vec<f64> = (0..bands * m)
            .map(|i| {
                let (k, j) = (i / m, i % m);
                [1.0, (k as f64 * 0.6).cos(), (k as f64 - 4.0).powi(2) / 16.0][j]
            })
            .collect();
        let u = CoarseScene::new(bands, rows, cols, 4, 5).with_spectra(&spectra, m);
        assert_eq!(u.domain_len(), m * u.plane());
        let mismatch = adjoint_mismatch(&u, 3);
        assert!(mismatch < 1e-5, "{mismatch}");
        // node (spectrum 2, row 1, col 2) alone: pixel (4, 8) of band k is spectra[k][2]
        let mut z = vec![0.0f32; u.domain_len()];
        z[2 * u.plane() + u.node_cols + 2] = 1.0;
        let mut cube = vec![0.0f32; u.range_len()];
        u.apply(&z, &mut cube);
        for k in 0..bands {
            let v = cube[(k * rows + 4) * cols + 8];
            assert!(
                (v as f64 - spectra[k * m + 2]).abs() < 1e-6,
                "band {k}: {v}"
            );
        }
        let z: Vec<f32> = (0..u.domain_len())
            .map(|i| ((i * 37) % 11) as f32 / 11.0)
            .collect();
        u.apply(&z, &mut cube);
        let back = u.nodes_of(&cube);
        let worst = z
            .iter()
            .zip(&back)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-4, "{worst}");
    }
}
