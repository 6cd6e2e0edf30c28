//! Optical blur on the detector: a separable Gaussian of σ detector pixels
//! applied to the dispersed image (docs/CONVENTIONS.md, the physical simulator), its
//! adjoint, and its exact derivative in σ — so the blur width can be a model
//! parameter that calibration fits.
//!
//! σ is the width of a continuous Gaussian PSF acting on the irradiance of
//! square pixels, as in a camera (and the oversampled simulator): pixel i's
//! light lands on pixel j with weight ∫∫ G_σ(u − v) over the two pixels, the
//! Gaussian convolved with the pixels' overlap triangle, sampled at d = j − i:
//! g_d = F(d+1) − 2F(d) + F(d−1), F(x) = x·Φ(x/σ) + σ·φ(x/σ) (the Gaussian's
//! second antiderivative), for |d| ≤ r = ⌈4σ⌉ + 1, normalised to sum 1 (a
//! blur moves light, it does not make or lose it). σ = 0 is the identity.
//! Sampling the Gaussian at integer offsets instead (the first version)
//! under-blurs: fitted to the 4× simulator at σ 0.5 px it needed σ ≈ 0.7.
//! Zero outside the frame: light blurred past the edge is lost, as on a real
//! sensor. The
//! matrix of a symmetric kernel with zero boundary is symmetric, so the
//! adjoint is the blur itself. [`Blurred`] composes the blur after any
//! [`LinearOperator`] whose range is a frame: y = B(σ) A x.
//!
//! A band's light spread along the dispersion ([`BandSpread`]: a real
//! camera's continuous spectrum) is, on a straight dispersion, one kernel for
//! every band, so it commutes with the band sum and joins the blur: along
//! the rows the taps are then the pixel kernel convolved with the spread's
//! shape (`GaussianBlur::with_band_spread`), down the columns the Gaussian's
//! alone. The dispersion's tilt α (≤ 1°: 0.035 px across a 2-px spread) and
//! the spacing's change along a curved or stepped dispersion are not in it.

use std::cell::RefCell;

use rayon::prelude::*;

use super::band_spread::BandSpread;
use super::operator::weighted_add_row;
use crate::error::{CassiError, Result};
use crate::linop::{AatNormaliser, LinearOperator, NonNegativeOperator, row_sum_majoriser};
use crate::simd::{Simd, kernel};

/// The widest blur accepted, detector pixels (one limit for the model, the
/// simulator and the mismatch vector).
pub use crate::params::MAX_BLUR_SIGMA_PX as MAX_SIGMA_PX;

/// A separable Gaussian blur of one width on frames of one shape.
#[derive(Debug, Clone)]
pub struct GaussianBlur {
    sigma: f64,
    rows: usize,
    cols: usize,
    /// g_{−r..=r}: down the columns, and along the rows without a spread.
    taps: Vec<f32>,
    /// ∂g/∂σ, same length.
    dtaps: Vec<f32>,
    /// Along the rows: g convolved with the band spread's shape (g itself
    /// for [`BandSpread::Point`]), and its σ-derivative.
    row_taps: Vec<f32>,
    row_dtaps: Vec<f32>,
    spread: BandSpread,
    /// The bands' spacing the spread spans, px (0 for a point).
    spacing_px: f64,
}

/// The widest band spacing a spread accepts, px.
pub const MAX_SPREAD_SPACING_PX: f64 = 8.0;

impl GaussianBlur {
    /// The blur of width `sigma_px` (0 = none) on `rows × cols` frames.
    pub fn new(sigma_px: f64, rows: usize, cols: usize) -> Result<Self> {
        if !(sigma_px.is_finite() && (0.0..=MAX_SIGMA_PX).contains(&sigma_px)) {
            return Err(CassiError::InvalidParameter {
                name: "blur_sigma_px",
                value: sigma_px,
                reason: format!("the blur width must lie in [0, {MAX_SIGMA_PX}] detector pixels"),
            });
        }
        let (taps, dtaps) = kernel(sigma_px);
        Ok(Self {
            sigma: sigma_px,
            rows,
            cols,
            row_taps: taps.clone(),
            row_dtaps: dtaps.clone(),
            taps,
            dtaps,
            spread: BandSpread::Point,
            spacing_px: 0.0,
        })
    }

    /// The blur of width `sigma_px` with each band's light spread along the
    /// rows as `spread` says, bands `spacing_px` apart (a point: [`Self::new`]).
    pub fn with_band_spread(
        sigma_px: f64,
        spread: BandSpread,
        spacing_px: f64,
        rows: usize,
        cols: usize,
    ) -> Result<Self> {
        let plain = Self::new(sigma_px, rows, cols)?;
        if spread == BandSpread::Point {
            return Ok(plain);
        }
        if !(spacing_px.is_finite() && spacing_px > 0.0 && spacing_px <= MAX_SPREAD_SPACING_PX) {
            return Err(CassiError::InvalidParameter {
                name: "band spacing",
                value: spacing_px,
                reason: format!(
                    "a band spread spans the bands' spacing: (0, {MAX_SPREAD_SPACING_PX}] px"
                ),
            });
        }
        let (row_taps, row_dtaps) = spread_kernel(sigma_px, spread, spacing_px);
        Ok(Self {
            row_taps,
            row_dtaps,
            spread,
            spacing_px,
            ..plain
        })
    }

    /// This blur (its σ and frame) with the bands' light spread as
    /// `spread` says, `spacing_px` apart.
    pub fn with_spread(&self, spread: BandSpread, spacing_px: f64) -> Result<Self> {
        Self::with_band_spread(self.sigma, spread, spacing_px, self.rows, self.cols)
    }

    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Where each band's light lies along the rows, and the spacing it spans.
    pub fn band_spread(&self) -> (BandSpread, f64) {
        (self.spread, self.spacing_px)
    }

    /// The kernel's radius r down the columns (taps −r ..= r).
    pub fn radius(&self) -> usize {
        self.taps.len() / 2
    }

    /// The normalised taps g_{−r..=r} down the columns.
    pub fn taps(&self) -> &[f32] {
        &self.taps
    }

    /// The normalised taps along the rows (the band spread's included).
    pub fn row_taps(&self) -> &[f32] {
        &self.row_taps
    }

    /// out ← B y for a `rows × cols` frame `y`; `tmp` is scratch of the same
    /// length.
    pub fn apply(&self, y: &[f32], out: &mut [f32], tmp: &mut [f32]) {
        self.separable(y, out, tmp, &self.row_taps, &self.taps);
    }

    /// out ← y convolved along each row only (the row taps; the crisp-cell
    /// model blurs down the columns itself).
    pub(crate) fn apply_along_rows(&self, y: &[f32], out: &mut [f32]) {
        debug_assert_eq!(y.len(), self.rows * self.cols);
        let r = self.row_taps.len() / 2;
        let simd = Simd::detect(false);
        out.par_chunks_mut(self.cols)
            .zip(y.par_chunks(self.cols))
            .for_each(|(o, src)| convolve_line(simd, src, o, &self.row_taps, r));
    }

    /// out ← (∂B/∂σ) y = (G′ ⊗ G + G ⊗ G′) y; `tmp` and `tmp2` are scratch.
    pub fn apply_derivative(&self, y: &[f32], out: &mut [f32], tmp: &mut [f32], tmp2: &mut [f32]) {
        // rows by G′, cols by G; then rows by G, cols by G′; summed
        self.separable(y, out, tmp, &self.row_taps, &self.dtaps);
        self.separable(y, tmp2, tmp, &self.row_dtaps, &self.taps);
        out.iter_mut().zip(tmp2.iter()).for_each(|(o, &t)| *o += t);
    }

    /// out ← (rows by `vertical`) ∘ (cols by `horizontal`) y.
    fn separable(
        &self,
        y: &[f32],
        out: &mut [f32],
        tmp: &mut [f32],
        horizontal: &[f32],
        vertical: &[f32],
    ) {
        let (rows, cols) = (self.rows, self.cols);
        debug_assert_eq!(y.len(), rows * cols);
        if horizontal.len() == 1
            && vertical.len() == 1
            && horizontal[0] == 1.0
            && vertical[0] == 1.0
        {
            out.copy_from_slice(y);
            return;
        }
        // along each row
        let simd = Simd::detect(false);
        let r = horizontal.len() / 2;
        tmp.par_chunks_mut(cols)
            .zip(y.par_chunks(cols))
            .for_each(|(t, src)| convolve_line(simd, src, t, horizontal, r));
        // along each column: output row i = Σ_k v_k · tmp row (i + k − r)
        let r = vertical.len() / 2;
        out.par_chunks_mut(cols).enumerate().for_each(|(i, o)| {
            o.fill(0.0);
            for (k, &w) in vertical.iter().enumerate() {
                let Some(src_row) = (i + k).checked_sub(r).filter(|&s| s < rows) else {
                    continue;
                };
                let src = &tmp[src_row * cols..(src_row + 1) * cols];
                weighted_add_row(simd, o, src, w);
            }
        });
    }
}

// Compiled for the baseline target and for AVX (picked at run time): the
// same arithmetic per element either way.
kernel!(convolve_line, convolve_line_port, convolve_line_avx,
    (src: &[f32], dst: &mut [f32], w: &[f32], r: usize) -> ()
    = convolve_line_body(src, dst, w, r));

/// dst[j] = Σ_k w_k · src[j + k − r], zero outside `src`. Each output sums
/// its taps in ascending k from 0.0 — in the edge loop one at a time, in
/// the interior one tap across all outputs (a loop LLVM vectorises) — so
/// every output is the same float sum either way.
#[inline(always)]
fn convolve_line_body(src: &[f32], dst: &mut [f32], w: &[f32], r: usize) {
    let n = src.len();
    let edge = |j: usize| {
        let lo = r.saturating_sub(j);
        let hi = w.len().min(n + r - j);
        let mut acc = 0.0f32;
        for k in lo..hi {
            acc += w[k] * src[j + k - r];
        }
        acc
    };
    // the interior: outputs whose whole window lies inside `src`
    let (a, b) = (r.min(n), n.saturating_sub(r).max(r.min(n)));
    for (j, d) in dst.iter_mut().enumerate().take(a) {
        *d = edge(j);
    }
    for (j, d) in dst.iter_mut().enumerate().skip(b) {
        *d = edge(j);
    }
    if b == a {
        return;
    }
    // here a = r (the interior is not empty only when n > 2r)
    let inner = &mut dst[a..b];
    inner.fill(0.0);
    for (k, &wk) in w.iter().enumerate() {
        // output j = a + i reads src[a + i + k − r] = src[i + k] (a = r)
        let s = &src[a + k - r..a + k - r + inner.len()];
        for (d, &v) in inner.iter_mut().zip(s) {
            *d += wk * v;
        }
    }
}

/// F(x) = x Φ(x/σ) + σ φ(x/σ), the Gaussian's second antiderivative, and
/// ∂F/∂σ = φ(x/σ); σ > 0.
fn second_antiderivative(sigma: f64) -> (impl Fn(f64) -> f64, impl Fn(f64) -> f64) {
    let pdf = |z: f64| (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let cdf = |z: f64| 0.5 * (1.0 + libm::erf(z / std::f64::consts::SQRT_2));
    (
        move |x: f64| x * cdf(x / sigma) + sigma * pdf(x / sigma),
        move |x: f64| pdf(x / sigma),
    )
}

/// (G_σ ∗ tri)(t) = F(t+1) − 2F(t) + F(t−1): the share of a unit square's
/// light, centred t pixels from a pixel's centre, that the pixel collects
/// through the blur — the taps' formula at any offset (the taps are its
/// integer samples, before normalising), for models that place a crisp
/// code between pixels (`cassi-bench`'s `blur_phase`). σ = 0: the triangle.
pub fn pixel_kernel(sigma: f64, t: f64) -> f64 {
    if sigma <= 0.0 {
        return (1.0 - t.abs()).max(0.0);
    }
    let (f, _) = second_antiderivative(sigma);
    f(t + 1.0) - 2.0 * f(t) + f(t - 1.0)
}

/// ∫_a^b (G_σ ∗ box)(d − t) dt: the share of the light on the strip [a, b]
/// of one pixel (a, b in that pixel's coordinates, −½ ≤ a ≤ b ≤ ½) that
/// the pixel `d` rows away collects through the blur — the kernel of a
/// crisp mask edge's two sides inside a pixel (`crisp_cells.rs`). The
/// whole pixel (a = −½, b = ½) gives [`pixel_kernel`]; σ = 0: the strip's
/// overlap with pixel d.
pub fn pixel_strip_kernel(sigma: f64, a: f64, b: f64, d: f64) -> f64 {
    // H(s) = ∫ (G ∗ box)(s) ds = F(s + ½) − F(s − ½)
    let strip = |h: &dyn Fn(f64) -> f64| h(d - a) - h(d - b);
    if sigma <= 0.0 {
        return strip(&|s: f64| (s + 0.5).clamp(0.0, 1.0));
    }
    let (f, _) = second_antiderivative(sigma);
    strip(&|s: f64| f(s + 0.5) - f(s - 0.5))
}

/// The normalised taps and their exact σ-derivative (the radius ⌈4σ⌉ + 1 is
/// held: the taps it adds or drops weigh < e⁻⁸).
fn kernel(sigma: f64) -> (Vec<f32>, Vec<f32>) {
    if sigma == 0.0 {
        return (vec![1.0], vec![0.0]);
    }
    let r = (4.0 * sigma).ceil() as i64 + 1;
    let (f, df) = second_antiderivative(sigma);
    let second = |g: &dyn Fn(f64) -> f64, i: i64| {
        let x = i as f64;
        g(x + 1.0) - 2.0 * g(x) + g(x - 1.0)
    };
    // The kernel is even: each tap from the offset −|d| and mirrored, where
    // F holds the tail itself (at +|d| it is a difference of numbers near
    // |d| and cancels). A tap below f32's resolution beside the centre is
    // dropped: kept, one came out 7e-39 (subnormal) on one side only at
    // σ 0.077, and GAP's normaliser of a pixel reached through it alone
    // turned the reconstruction into NaN.
    even_taps(r, |i| {
        (second(&f, -i.abs()).max(0.0), second(&df, -i.abs()))
    })
}

/// The taps −r ..= r from `tap(i)` = (raw weight, its σ-derivative),
/// normalised to sum 1, with their exact σ-derivative; a tap below f32's
/// resolution beside the centre is dropped (see [`kernel`]).
fn even_taps(r: i64, tap: impl Fn(i64) -> (f64, f64)) -> (Vec<f32>, Vec<f32>) {
    let centre = tap(0).0;
    let (e, de): (Vec<f64>, Vec<f64>) = (-r..=r)
        .map(|i| {
            let (e, de) = tap(i);
            if e < centre * f64::from(f32::EPSILON) {
                (0.0, 0.0)
            } else {
                (e, de)
            }
        })
        .unzip();
    let s: f64 = e.iter().sum();
    let ds: f64 = de.iter().sum();
    let taps = e.iter().map(|&ei| (ei / s) as f32).collect();
    let dtaps = e
        .iter()
        .zip(&de)
        .map(|(&ei, &dei)| ((dei * s - ei * ds) / (s * s)) as f32)
        .collect();
    (taps, dtaps)
}

/// The row taps of the pixel kernel (σ) convolved with a band spread of
/// `spacing` px, normalised, and their σ-derivative: the pixel kernel
/// ([`pixel_kernel`]) averaged over the spread's positions
/// ([`BandSpread::positions`], 64 a side).
fn spread_kernel(sigma: f64, spread: BandSpread, spacing: f64) -> (Vec<f32>, Vec<f32>) {
    let positions = spread.positions(&[(-spacing, 0.0), (0.0, 0.0), (spacing, 0.0)], 1, 64);
    let reach = positions.iter().map(|p| p.0.0.abs()).fold(0.0, f64::max);
    let r = (4.0 * sigma + reach).ceil() as i64 + 1;
    // without blur the taps do not depend on σ
    let df = (sigma > 0.0).then(|| second_antiderivative(sigma).1);
    let d_pixel = |x: f64| match &df {
        Some(df) => df(x + 1.0) - 2.0 * df(x) + df(x - 1.0),
        None => 0.0,
    };
    // even (the spread is symmetric): each tap from −|d|, each term of it
    // from −|d − t| (the kernel's tails held, not cancelled)
    even_taps(r, |i| {
        let d = -(i.abs() as f64);
        positions.iter().fold((0.0, 0.0), |(e, de), &((t, _), w)| {
            let x = -(d - t).abs();
            (e + w * pixel_kernel(sigma, x).max(0.0), de + w * d_pixel(x))
        })
    })
}

/// y = B(σ) A x: a non-negative operator whose range is a `rows × cols`
/// frame, followed by the optical blur. B and A are both non-negative, so
/// the solvers' normaliser is the row-sum majoriser B A Aᵀ B 𝟙.
pub struct Blurred<A> {
    inner: A,
    blur: GaussianBlur,
}

thread_local! {
    /// The products' range-sized buffers (A x or B y, the row pass, the
    /// derivative's second term), shared by every [`Blurred`] on the thread
    /// ([`crate::scratch`]).
    static SCRATCH: RefCell<[Vec<f32>; 3]> = RefCell::default();
}

/// Runs `f` with the thread's scratch, the first `n` buffers `len` long
/// (contents unspecified).
fn with_scratch<R>(n: usize, len: usize, f: impl FnOnce(&mut [Vec<f32>; 3]) -> R) -> R {
    crate::scratch::with_taken(&SCRATCH, |bufs| {
        bufs[..n].iter_mut().for_each(|b| b.resize(len, 0.0));
        f(bufs)
    })
}

impl<A: NonNegativeOperator> Blurred<A> {
    /// `inner` followed by a blur of `sigma_px` on its `rows × cols` range.
    pub fn new(inner: A, sigma_px: f64, rows: usize, cols: usize) -> Result<Self> {
        if rows * cols != inner.range_len() {
            return Err(CassiError::Shape {
                what: "the blurred operator's detector".into(),
                got: format!("{rows}×{cols}"),
                expected: format!("{} pixels (the operator's range)", inner.range_len()),
            });
        }
        Ok(Self {
            inner,
            blur: GaussianBlur::new(sigma_px, rows, cols)?,
        })
    }

    /// `inner` followed by `blur` (its frame must be `inner`'s range).
    pub fn with_blur(inner: A, blur: GaussianBlur) -> Result<Self> {
        if blur.rows * blur.cols != inner.range_len() {
            return Err(CassiError::Shape {
                what: "the blurred operator's detector".into(),
                got: format!("{}×{}", blur.rows, blur.cols),
                expected: format!("{} pixels (the operator's range)", inner.range_len()),
            });
        }
        Ok(Self { inner, blur })
    }

    pub fn into_inner(self) -> A {
        self.inner
    }

    pub fn inner(&self) -> &A {
        &self.inner
    }

    pub fn blur(&self) -> &GaussianBlur {
        &self.blur
    }

    /// y ← B (A x) with A x written by `inner` (a product of A other than
    /// [`LinearOperator::apply`], e.g. from a cube made row by row).
    pub(crate) fn apply_after(&self, inner: impl FnOnce(&mut [f32]), y: &mut [f32]) {
        with_scratch(2, self.range_len(), |[ax, tmp, _]| {
            inner(ax);
            self.blur.apply(ax, y, tmp);
        })
    }

    /// Runs `f` with Bᵀ y = B y, the blurred frame A's adjoint reads.
    pub(crate) fn adjoint_before<T>(&self, y: &[f32], f: impl FnOnce(&[f32]) -> T) -> T {
        with_scratch(2, self.range_len(), |[by, tmp, _]| {
            self.blur.apply(y, by, tmp);
            f(by)
        })
    }

    /// out ← (∂B/∂σ) A x: the derivative of the model in the blur width.
    pub fn apply_sigma_derivative(&self, x: &[f32], out: &mut [f32]) {
        with_scratch(3, self.range_len(), |[ax, tmp, tmp2]| {
            self.inner.apply(x, ax);
            self.blur.apply_derivative(ax, out, tmp, tmp2);
        })
    }
}

impl<A: NonNegativeOperator> NonNegativeOperator for Blurred<A> {}

impl<A: NonNegativeOperator> LinearOperator for Blurred<A> {
    fn domain_len(&self) -> usize {
        self.inner.domain_len()
    }

    fn range_len(&self) -> usize {
        self.inner.range_len()
    }

    fn apply(&self, x: &[f32], y: &mut [f32]) {
        with_scratch(2, self.range_len(), |[ax, tmp, _]| {
            self.inner.apply(x, ax);
            self.blur.apply(ax, y, tmp);
        })
    }

    fn aat_normaliser(&self) -> Option<AatNormaliser> {
        Some(row_sum_majoriser(self))
    }

    fn adjoint(&self, y: &[f32], x: &mut [f32]) {
        // B is symmetric (symmetric kernel, zero boundary): Bᵀ = B
        with_scratch(2, self.range_len(), |[by, tmp, _]| {
            self.blur.apply(y, by, tmp);
            self.inner.adjoint(by, x);
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Mismatch;
    use crate::linop::adjoint_mismatch;
    use crate::optics::{CassiOperator, DispersionModel};
    use crate::synth::random_binary_mask;

    /// Every compiled copy of the line convolution gives the portable copy's bits, on
    /// lines shorter and longer than the taps and not whole vectors.
    #[test]
    fn every_compiled_copy_of_the_line_convolution_gives_the_portable_bits() {
        let taps: Vec<f32> = [0.05f32, 0.2, 0.5, 0.2, 0.05].to_vec();
        for n in [1, 3, 4, 5, 9, 17, 40, 333] {
            let src: Vec<f32> = (0..n).map(|i| ((i * 7919) % 101) as f32 / 101.0).collect();
            let mut portable = vec![0.0f32; n];
            convolve_line(Simd::Portable, &src, &mut portable, &taps, 2);
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            for simd in Simd::available() {
                let mut wide = vec![0.0f32; n];
                convolve_line(simd, &src, &mut wide, &taps, 2);
                assert_eq!(bits(&portable), bits(&wide), "n = {n}, {simd:?}");
            }
            // and it is the convolution: an interior output by hand
            if n >= 5 {
                let j = 2;
                let want: f32 = (0..5).fold(0.0, |acc, k| acc + taps[k] * src[j + k - 2]);
                assert_eq!(portable[j], want);
            }
        }
    }

    fn frame_blur(sigma: f64, rows: usize, cols: usize, y: &[f32]) -> Vec<f32> {
        let b = GaussianBlur::new(sigma, rows, cols).unwrap();
        let (mut out, mut tmp) = (vec![0.0; y.len()], vec![0.0; y.len()]);
        b.apply(y, &mut out, &mut tmp);
        out
    }

    /// A band spread's row taps: without blur a box of one spacing (2 px)
    /// through the pixels' triangle is ¼ ½ ¼, a hat of two 1/24 ¼ 5/12 ¼
    /// 1/24 (worked by hand); with blur their variance is the three parts'
    /// sum, σ² + 1/6 + the spread's (w²/12 or w²/6); down the columns the
    /// Gaussian's alone; a point is the plain blur.
    #[test]
    fn a_band_spread_adds_its_shape_along_the_rows_only() {
        let taps = |spread, spacing| {
            let b = GaussianBlur::with_band_spread(0.0, spread, spacing, 4, 9).unwrap();
            assert_eq!(b.taps(), &[1.0]);
            b.row_taps().to_vec()
        };
        // the taps without the zeros at their ends (the spread sampled at 64
        // positions a side: within 1e-4 of the integrals)
        let close = |got: &[f32], want: &[f64]| {
            let lo = got.iter().position(|v| v.abs() > 1e-7).unwrap();
            let hi = got.iter().rposition(|v| v.abs() > 1e-7).unwrap();
            let got = &got[lo..=hi];
            got.len() == want.len()
                && got
                    .iter()
                    .zip(want)
                    .all(|(&g, &w)| (g as f64 - w).abs() < 1e-4)
        };
        let uniform = taps(BandSpread::Uniform, 2.0);
        assert!(close(&uniform, &[0.25, 0.5, 0.25]), "{uniform:?}");
        let linear = taps(BandSpread::Linear, 2.0);
        let want = [1.0 / 24.0, 0.25, 5.0 / 12.0, 0.25, 1.0 / 24.0];
        assert!(close(&linear, &want), "{linear:?}");
        // (sampling at whole pixels keeps the variance where the kernel is
        // smooth: with blur)
        for sigma in [0.3, 0.7] {
            for (spread, share) in [(BandSpread::Uniform, 12.0), (BandSpread::Linear, 6.0)] {
                for w in [1.9, 2.1] {
                    let b = GaussianBlur::with_band_spread(sigma, spread, w, 4, 9).unwrap();
                    let r = b.row_taps().len() as f64 / 2.0 - 0.5;
                    let (sum, var) =
                        b.row_taps()
                            .iter()
                            .enumerate()
                            .fold((0.0, 0.0), |(s, v), (i, &t)| {
                                let d = i as f64 - r;
                                (s + t as f64, v + t as f64 * d * d)
                            });
                    let want = sigma * sigma + 1.0 / 6.0 + w * w / share;
                    assert!((sum - 1.0).abs() < 1e-6, "{spread:?} σ {sigma}: sum {sum}");
                    assert!(
                        (var - want).abs() < 2e-3,
                        "{spread:?} σ {sigma} w {w}: {var} vs {want}"
                    );
                    assert_eq!(b.taps(), GaussianBlur::new(sigma, 4, 9).unwrap().taps());
                }
            }
        }
        let point = GaussianBlur::with_band_spread(0.5, BandSpread::Point, 2.0, 4, 9).unwrap();
        assert_eq!(point.row_taps(), point.taps());
        for bad in [0.0, -1.0, f64::NAN, 9.0] {
            let e = GaussianBlur::with_band_spread(0.5, BandSpread::Uniform, bad, 4, 9)
                .unwrap_err()
                .to_string();
            assert!(e.contains("band spacing"), "{e}");
        }
    }

    /// With a spread, ∂B/∂σ still matches central differences.
    #[test]
    fn the_sigma_derivative_with_a_band_spread_matches_finite_differences() {
        let (rows, cols) = (13, 21);
        for sigma in [0.3, 0.6] {
            let rel = sigma_derivative_error(sigma, rows, cols, &|s| {
                GaussianBlur::with_band_spread(s, BandSpread::Linear, 2.05, rows, cols).unwrap()
            });
            assert!(rel < 2e-3, "σ {sigma}: relative error {rel}");
        }
    }

    /// ‖∂B/∂σ y − (B(σ+h) − B(σ−h)) y / 2h‖ / ‖the difference‖ for one
    /// test frame y, B = `blur(σ)`, at a step h that keeps the radius.
    fn sigma_derivative_error(
        sigma: f64,
        rows: usize,
        cols: usize,
        blur: &dyn Fn(f64) -> GaussianBlur,
    ) -> f64 {
        let y: Vec<f32> = (0..rows * cols)
            .map(|i| ((i * 7919) % 101) as f32 / 101.0)
            .collect();
        let n = y.len();
        let (mut d, mut t1, mut t2) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        blur(sigma).apply_derivative(&y, &mut d, &mut t1, &mut t2);
        let at = |s: f64| {
            let (mut out, mut tmp) = (vec![0.0; n], vec![0.0; n]);
            blur(s).apply(&y, &mut out, &mut tmp);
            out
        };
        let h = 1e-3;
        let (hi, lo) = (at(sigma + h), at(sigma - h));
        let (mut err, mut norm) = (0.0f64, 0.0f64);
        for i in 0..n {
            let fd = (hi[i] as f64 - lo[i] as f64) / (2.0 * h);
            err += (fd - d[i] as f64).powi(2);
            norm += fd * fd;
        }
        (err / norm).sqrt()
    }

    #[test]
    fn a_point_spreads_symmetrically_and_keeps_its_light_away_from_edges() {
        let (rows, cols) = (21, 23);
        let mut y = vec![0.0f32; rows * cols];
        y[10 * cols + 11] = 1.0;
        let out = frame_blur(0.7, rows, cols, &y);
        let total: f32 = out.iter().sum();
        assert!((total - 1.0).abs() < 1e-5, "light kept: {total}");
        for (dr, dc) in [(1, 0), (0, 1), (2, 1), (3, 3)] {
            let at = |r: usize, c: usize| out[r * cols + c];
            let v = at(10 + dr, 11 + dc);
            assert!((v - at(10 - dr, 11 - dc)).abs() < 1e-7);
            assert!((v - at(10 + dc, 11 + dr)).abs() < 1e-7, "isotropic");
        }
        // each weight is the 1-D pixel-to-pixel transfer squared (or
        // multiplied): the light of a uniformly lit unit pixel that a
        // continuous Gaussian PSF of σ 0.7 puts on the pixel d away,
        // integrated numerically here (midpoint rule, 400² points)
        let transfer = |d: f64| {
            let n = 400;
            let g = |t: f64| {
                (-t * t / (2.0 * 0.49)).exp() / (0.7 * (2.0 * std::f64::consts::PI).sqrt())
            };
            let mut acc = 0.0;
            for a in 0..n {
                for b in 0..n {
                    let (u, v) = ((a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64);
                    acc += g(d + v - u);
                }
            }
            acc / (n * n) as f64
        };
        let (t0, t1, t2) = (transfer(0.0), transfer(1.0), transfer(2.0));
        assert!(
            (out[10 * cols + 11] as f64 - t0 * t0).abs() < 2e-5,
            "{} {}",
            out[10 * cols + 11],
            t0 * t0
        );
        assert!((out[11 * cols + 11] as f64 - t0 * t1).abs() < 2e-5);
        assert!((out[12 * cols + 13] as f64 - t2 * t2).abs() < 2e-5);
        // σ = 0 is the identity
        assert_eq!(frame_blur(0.0, rows, cols, &y), y);
    }

    /// The taps are even (the blur is its own adjoint) and none is below
    /// f32's resolution beside the centre, at any width: at σ 0.077 the
    /// outermost tap once came out 7e-39 on the left and 0 on the right.
    #[test]
    fn the_taps_are_even_and_none_is_rounding_noise() {
        for i in 1..=300 {
            let sigma = i as f64 * 0.005;
            let b = GaussianBlur::new(sigma, 4, 4).unwrap();
            let (taps, r) = (b.taps(), b.radius());
            let centre = taps[r];
            for d in 1..=r {
                assert_eq!(taps[r - d], taps[r + d], "σ {sigma}, tap {d}");
                assert_eq!(b.dtaps[r - d], b.dtaps[r + d], "σ {sigma}, ∂ tap {d}");
                let t = taps[r + d];
                assert!(
                    t == 0.0 || t >= centre * f32::EPSILON,
                    "σ {sigma}, tap {d}: {t:e}"
                );
            }
        }
    }

    #[test]
    fn light_blurred_past_the_edge_is_lost() {
        let (rows, cols) = (9, 9);
        let mut y = vec![0.0f32; rows * cols];
        y[0] = 1.0; // a corner
        let total: f32 = frame_blur(1.0, rows, cols, &y).iter().sum();
        // one quarter of a 2-D Gaussian plus the half axes: well below 1
        assert!(total < 0.5 && total > 0.25, "{total}");
    }

    #[test]
    fn the_blurred_operator_has_an_exact_adjoint_for_every_tapped_model() {
        let mask = random_binary_mask(24, 20, 0.5, 3).unwrap();
        let mut m = Mismatch::paper();
        m.a1 = 1.87;
        for model in DispersionModel::TAPPED {
            let a = CassiOperator::with_mismatch(&mask, 6, &m, model).unwrap();
            let (rows, cols) = a.measurement_shape();
            for sigma in [0.0, 0.35, 0.7, 1.6] {
                let b = Blurred::new(a.clone(), sigma, rows, cols).unwrap();
                let e = adjoint_mismatch(&b, 11);
                assert!(e < 1e-5, "{model:?} σ {sigma}: {e}");
            }
        }
    }

    /// Operators of different sizes share the thread's scratch: each gives
    /// the same numbers whatever ran before it.
    #[test]
    fn interleaved_operators_share_scratch_without_changing_results() {
        let m = Mismatch::paper();
        let ops: Vec<_> = [(24, 20), (9, 31)]
            .into_iter()
            .map(|(h, w)| {
                let mask = random_binary_mask(h, w, 0.5, 5).unwrap();
                let a =
                    CassiOperator::with_mismatch(&mask, 4, &m, DispersionModel::Subpixel).unwrap();
                let (rows, cols) = a.measurement_shape();
                Blurred::new(a, 0.6, rows, cols).unwrap()
            })
            .collect();
        let mut rng = crate::Rng::new(8);
        let inputs: Vec<(Vec<f32>, Vec<f32>)> = ops
            .iter()
            .map(|b| {
                let x = (0..b.domain_len()).map(|_| rng.uniform() as f32).collect();
                let y = (0..b.range_len()).map(|_| rng.uniform() as f32).collect();
                (x, y)
            })
            .collect();
        let run = |b: &Blurred<CassiOperator>, (x, y): &(Vec<f32>, Vec<f32>)| {
            let (mut ax, mut aty, mut dx) = (
                vec![0.0; b.range_len()],
                vec![0.0; b.domain_len()],
                vec![0.0; b.range_len()],
            );
            b.apply(x, &mut ax);
            b.adjoint(y, &mut aty);
            b.apply_sigma_derivative(x, &mut dx);
            (ax, aty, dx)
        };
        let first: Vec<_> = ops.iter().zip(&inputs).map(|(b, i)| run(b, i)).collect();
        for (k, (b, i)) in ops.iter().zip(&inputs).enumerate().rev() {
            assert_eq!(run(b, i), first[k], "operator {k}");
        }
    }

    #[test]
    fn the_sigma_derivative_matches_finite_differences() {
        let (rows, cols) = (17, 19);
        for sigma in [0.3, 0.55, 0.8, 1.7] {
            let rel = sigma_derivative_error(sigma, rows, cols, &|s| {
                GaussianBlur::new(s, rows, cols).unwrap()
            });
            assert!(rel < 2e-3, "σ {sigma}: relative error {rel}");
        }
    }

    #[test]
    fn the_model_derivative_is_the_blur_derivative_of_a_x() {
        let mask = random_binary_mask(12, 10, 0.5, 5).unwrap();
        let a =
            CassiOperator::with_mismatch(&mask, 3, &Mismatch::paper(), DispersionModel::Subpixel)
                .unwrap();
        let (rows, cols) = a.measurement_shape();
        let x: Vec<f32> = (0..a.domain_len())
            .map(|i| (i % 13) as f32 / 13.0)
            .collect();
        let h = 1e-3;
        let at = |s: f64| {
            let b = Blurred::new(a.clone(), s, rows, cols).unwrap();
            let mut y = vec![0.0; b.range_len()];
            b.apply(&x, &mut y);
            y
        };
        let b = Blurred::new(a.clone(), 0.6, rows, cols).unwrap();
        let mut d = vec![0.0; b.range_len()];
        b.apply_sigma_derivative(&x, &mut d);
        let (hi, lo) = (at(0.6 + h), at(0.6 - h));
        let worst = d
            .iter()
            .zip(hi.iter().zip(&lo))
            .map(|(&d, (&p, &m))| (d as f64 - (p as f64 - m as f64) / (2.0 * h)).abs())
            .fold(0.0, f64::max);
        let scale = d.iter().fold(0.0f32, |m, v| m.max(v.abs())) as f64;
        assert!(worst < 2e-3 * scale, "{worst} vs {scale}");
    }

    /// The kernel at any offset: its integer samples are the taps, it
    /// collects all of a square's light summed over the pixels at any
    /// offset, it is the triangle without blur, and it moves with t.
    #[test]
    fn the_pixel_kernel_is_the_taps_between_pixels() {
        for sigma in [0.3, 0.5, 1.2] {
            let blur = GaussianBlur::new(sigma, 9, 9).unwrap();
            let r = blur.radius() as i64;
            for (i, &tap) in (-r..=r).zip(blur.taps()) {
                assert!(
                    (pixel_kernel(sigma, i as f64) - tap as f64).abs() < 1e-6,
                    "σ {sigma} {i}"
                );
            }
            for f in [0.0, 0.25, 0.5, 0.8] {
                let total: f64 = (-12..=12).map(|i| pixel_kernel(sigma, i as f64 - f)).sum();
                assert!((total - 1.0).abs() < 1e-9, "σ {sigma} f {f}: {total}");
            }
            // a square half a pixel off lands evenly on its two neighbours
            assert!((pixel_kernel(sigma, 0.5) - pixel_kernel(sigma, -0.5)).abs() < 1e-12);
            assert!(pixel_kernel(sigma, 0.0) > pixel_kernel(sigma, 0.5));
        }
        for t in [-1.5, -0.75, 0.0, 0.3, 1.0] {
            assert_eq!(pixel_kernel(0.0, t), (1.0 - f64::abs(t)).max(0.0));
        }
    }

    /// The two strips of a pixel split at any edge add up to the whole
    /// pixel's kernel, each carries its width's share of the light, and
    /// the upper strip's lands above the lower one's.
    #[test]
    fn a_pixels_strips_add_up_to_its_kernel() {
        for sigma in [0.0, 0.3, 0.6] {
            for edge in [-0.5, -0.2, 0.1, 0.45] {
                let mut light = [0.0f64; 2];
                let mut centre = [0.0f64; 2];
                for d in -8..=8 {
                    let d = d as f64;
                    let (top, bottom) = (
                        pixel_strip_kernel(sigma, -0.5, edge, d),
                        pixel_strip_kernel(sigma, edge, 0.5, d),
                    );
                    assert!((top + bottom - pixel_kernel(sigma, d)).abs() < 1e-12);
                    assert!(top >= -1e-15 && bottom >= -1e-15);
                    light[0] += top;
                    light[1] += bottom;
                    centre[0] += top * d;
                    centre[1] += bottom * d;
                }
                let widths = [edge + 0.5, 0.5 - edge];
                for s in 0..2 {
                    assert!((light[s] - widths[s]).abs() < 1e-9, "σ {sigma} edge {edge}");
                }
                // blurred, the upper strip's light lands above the lower one's
                if sigma > 0.0 && widths[0] > 0.0 && widths[1] > 0.0 {
                    assert!(centre[0] / light[0] < centre[1] / light[1]);
                }
            }
        }
    }

    #[test]
    fn widths_and_shapes_are_checked() {
        assert!(GaussianBlur::new(-0.1, 4, 4).is_err());
        assert!(GaussianBlur::new(f64::NAN, 4, 4).is_err());
        let e = GaussianBlur::new(9.0, 4, 4).unwrap_err().to_string();
        assert!(e.contains("blur_sigma_px"), "{e}");
        let mask = random_binary_mask(8, 8, 0.5, 1).unwrap();
        let a = CassiOperator::with_mismatch(
            &mask,
            2,
            &Mismatch::nominal(2.0),
            DispersionModel::Rounded,
        )
        .unwrap();
        assert!(Blurred::new(a, 0.5, 8, 8).is_err());
    }
}
