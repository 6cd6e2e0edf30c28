//! The single-disperser CASSI operator y = Σ_k shift_k(m̃ ⊙ x_k) and its
//! exact adjoint, behind [`LinearOperator`]. For the dispersed-mask model
//! the mask multiplies where the light lands instead:
//! y = Σ_k M_k ⊙ shift_k(x_k), M_k the mask moved by the pose and band k's
//! offset, sampled once on the detector grid.

use rayon::prelude::*;

use super::dispersion::{Dispersion, DispersionModel, Tap};
use super::warp::{LandingMasks, warp_mask};
use crate::cube::{Cube, Frame, Mask, Measurement};
use crate::error::{CassiError, Result, shape_error};
use crate::linop::{
    AatNormaliser, LinearOperator, NonNegativeOperator, NormaliserKind, row_sum_majoriser,
};
use crate::params::{MaskPose, Mismatch};
use crate::simd::{Simd, kernel};
use std::sync::OnceLock;

/// Tolerance on the [0, 1] mask range (stored masks carry rounding noise).
const MASK_RANGE_SLACK: f32 = 1e-3;

/// A CASSI forward model for one effective mask (already warped) and one
/// dispersion. Cubes are (L, H, W) with (H, W) the mask shape; measurements
/// are (H, W + extra_cols). Light dispersed above row 0 or below row H−1 is
/// lost (and the adjoint reads nothing from there).
#[derive(Debug, Clone)]
pub struct CassiOperator {
    mask: Mask,
    dispersion: Dispersion,
    det_cols: usize,
    /// The dispersed-mask model's band masks (`None`: the mask multiplies
    /// at the source pixel).
    landing: Option<Box<Landing>>,
}

/// The band masks of the dispersed-mask model: computed row by row inside a
/// forward (a calibration's candidate operator is applied once: no 57 MB
/// per 660² candidate), stored whole at the first use that reads them more
/// than once (adjoint, normaliser: an iterative solver).
#[derive(Debug, Clone)]
struct Landing {
    masks: LandingMasks,
    /// Band-major, rows × det_cols per band.
    stored: OnceLock<Vec<f32>>,
    /// The pose, for [`CassiOperator::mask`] (the nominal mask is the
    /// band masks').
    pose: MaskPose,
    /// The pose-warped mask on the mask grid: no product reads it, so it is
    /// warped only when asked for (it cost a fifth of a 660² calibration
    /// candidate's time).
    posed: OnceLock<Mask>,
}

impl Landing {
    fn stored(&self) -> &[f32] {
        self.stored.get_or_init(|| self.masks.materialise())
    }
}

/// Checks a mask is finite and in [0, 1] (transmission), naming `what`.
pub fn validate_mask(mask: &Mask, what: &str) -> Result<()> {
    mask.check_finite(what)?;
    if mask.rows() == 0 || mask.cols() == 0 {
        return Err(shape_error(
            what,
            format!("{}×{}", mask.rows(), mask.cols()),
            "at least 1×1",
        ));
    }
    let (lo, hi) = mask.min_max();
    if lo < -MASK_RANGE_SLACK || hi > 1.0 + MASK_RANGE_SLACK {
        return Err(CassiError::InvalidParameter {
            name: "mask",
            value: if lo < 0.0 { lo as f64 } else { hi as f64 },
            reason: format!(
                "{what} values span [{lo}, {hi}]; a coded aperture is a transmission in [0, 1] (divide an 8-bit mask by 255)"
            ),
        });
    }
    Ok(())
}

impl CassiOperator {
    /// The operator for an effective `mask` (what the detector sees, after any
    /// misalignment) and a `dispersion`.
    pub fn new(mask: Mask, dispersion: Dispersion) -> Result<Self> {
        validate_mask(&mask, "mask")?;
        let det_cols = mask.cols() + dispersion.extra_cols();
        Ok(Self {
            mask,
            dispersion,
            det_cols,
            landing: None,
        })
    }

    /// The true operator of an instrument whose mask `nominal_mask` is
    /// misplaced and whose prism drifted as `mismatch` says. A blurred
    /// `mismatch` is refused (its operator is a
    /// [`ModelOperator`](super::ModelOperator)): dropping the blur silently
    /// would fit the wrong instrument.
    pub fn with_mismatch(
        nominal_mask: &Mask,
        bands: usize,
        mismatch: &Mismatch,
        model: DispersionModel,
    ) -> Result<Self> {
        mismatch.validate()?;
        if mismatch.blur_sigma_px != 0.0 {
            return Err(CassiError::InvalidParameter {
                name: "blur_sigma_px",
                value: mismatch.blur_sigma_px,
                reason: "the sharp CASSI operator has no blur; build a ModelOperator".into(),
            });
        }
        let dispersion = Dispersion::new(bands, mismatch.dispersion(), model)?;
        Self::posed(nominal_mask, mismatch.pose(), dispersion)
    }

    /// The operator of `nominal_mask` moved by `pose`, its light landing
    /// as `dispersion` says (any band positions, e.g. a
    /// [`Dispersion::shifted_along`]; a tapped model's).
    pub fn posed(nominal_mask: &Mask, pose: MaskPose, dispersion: Dispersion) -> Result<Self> {
        let model = dispersion.model();
        if model.places_cells() {
            return Err(CassiError::Meaningless {
                what: format!("a tapped CASSI operator for the {} model", model.name()),
                reason: "that model blurs each mask cell where it lands; build a ModelOperator"
                    .into(),
            });
        }
        validate_mask(nominal_mask, "nominal mask")?;
        let bands = dispersion.bands();
        if !model.samples_mask_per_band() {
            return Self::new(warp_mask(nominal_mask, &pose), dispersion);
        }
        let (rows, det_cols) = (
            nominal_mask.rows(),
            nominal_mask.cols() + dispersion.extra_cols(),
        );
        crate::limits::check_elements(
            "the dispersed-mask model's band masks",
            &[bands, rows, det_cols],
            "one mask per band on the detector grid",
        )?;
        let offsets: Vec<(f64, f64)> = (0..bands).map(|k| dispersion.offset(k)).collect();
        Ok(Self {
            // its shape only: the products read the band masks
            mask: nominal_mask.clone(),
            dispersion,
            det_cols,
            landing: Some(Box::new(Landing {
                masks: LandingMasks::new(nominal_mask, &pose, offsets, rows, det_cols),
                stored: OnceLock::new(),
                pose,
                posed: OnceLock::new(),
            })),
        })
    }

    /// The mask that multiplies band `k`'s light from source row `r` on its
    /// way to detector row `yr` at detector column `c0` onward (`cols` long).
    #[inline]
    fn mask_slice(&self, k: usize, r: usize, yr: usize, c0: usize) -> &[f32] {
        match &self.landing {
            None => self.mask.row(r),
            Some(_) => self.landed_mask(k, yr, c0, self.mask.cols()),
        }
    }

    /// The stored band mask of band `k` on detector row `yr`, `len` columns
    /// from `c0` (the dispersed-mask model's; its rows are the detector's).
    #[inline]
    fn landed_mask(&self, k: usize, yr: usize, c0: usize, len: usize) -> &[f32] {
        let l = self.landing.as_ref().expect("a dispersed-mask operator");
        let start = (k * self.mask.rows() + yr) * self.det_cols + c0;
        &l.stored()[start..start + len]
    }

    /// The effective mask on the mask grid (the nominal one moved by the
    /// pose).
    pub fn mask(&self) -> &Mask {
        match &self.landing {
            None => &self.mask,
            Some(l) => l
                .posed
                .get_or_init(|| warp_mask(l.masks.nominal(), &l.pose)),
        }
    }
    pub fn dispersion(&self) -> &Dispersion {
        &self.dispersion
    }
    pub fn bands(&self) -> usize {
        self.dispersion.bands()
    }
    /// (bands, rows, cols) of the cubes this operator takes.
    pub fn cube_shape(&self) -> (usize, usize, usize) {
        (self.bands(), self.mask.rows(), self.mask.cols())
    }
    /// (rows, detector cols) of the measurements it makes.
    pub fn measurement_shape(&self) -> (usize, usize) {
        (self.mask.rows(), self.det_cols)
    }

    /// y = A x for a cube of [`Self::cube_shape`].
    pub fn forward(&self, cube: &Cube) -> Result<Measurement> {
        checked_forward(self, self.cube_shape(), self.measurement_shape(), cube)
    }

    /// x = Aᵀ y for a measurement of [`Self::measurement_shape`].
    pub fn back_project(&self, measurement: &Measurement) -> Result<Cube> {
        if measurement.shape() != self.measurement_shape() {
            let (h, wd) = self.measurement_shape();
            let (mh, mw) = measurement.shape();
            return Err(shape_error(
                "measurement",
                format!("{mh}×{mw}"),
                format!("{h}×{wd}"),
            ));
        }
        let (l, h, w) = self.cube_shape();
        let mut x = Cube::zeros(l, h, w);
        self.adjoint(measurement.as_slice(), x.as_mut_slice());
        Ok(x)
    }

    /// diag(A Aᵀ) as a detector frame: Σ over the (band, pixel, tap) that hit
    /// each detector pixel of (weight · mask)². GAP's normaliser.
    pub fn diag_aat(&self) -> Frame {
        self.diag_product(self)
    }

    /// An operator of the same form with any mask values and any taps, not
    /// validated: A is linear in the mask and in the tap weights, so its
    /// derivative along a calibration parameter is such an operator (mask
    /// ∂m̃/∂p with the same taps, or the same mask with ∂w/∂p). The taps
    /// must land inside this operator's detector.
    pub(crate) fn derivative(&self, mask: Frame, dispersion: Dispersion) -> Self {
        debug_assert_eq!(mask.shape(), self.mask.shape());
        debug_assert!((0..dispersion.bands()).all(|k| {
            dispersion
                .taps(k)
                .iter()
                .all(|t| t.col >= 0 && t.col as usize <= self.dispersion.extra_cols())
        }));
        debug_assert!(
            self.landing.is_none(),
            "the dispersed-mask model has no derivative operator"
        );
        Self {
            mask,
            dispersion,
            det_cols: self.det_cols,
            landing: None,
        }
    }

    /// Σ_k Σ_t w_t · w'_t · shift_t(m ⊙ m'), pairing the taps of `self` and
    /// `other` by position: diag(A Aᵀ) when `other` is `self`, and half the
    /// derivative of diag(A Aᵀ) along a parameter when `other` is the
    /// operator's derivative there ([`Self::derivative`]).
    pub(crate) fn diag_product(&self, other: &CassiOperator) -> Frame {
        let (rows, det_cols) = self.measurement_shape();
        let cols = self.mask.cols();
        // (tap, paired weight) in band and tap order
        let taps: Vec<(usize, &super::dispersion::Tap, f32)> = (0..self.bands())
            .flat_map(|k| {
                self.dispersion.taps(k).iter().map(move |tap| {
                    let w: f32 = other
                        .dispersion
                        .taps(k)
                        .iter()
                        .filter(|t| t.row == tap.row && t.col == tap.col)
                        .map(|t| tap.weight * t.weight)
                        .sum();
                    (k, tap, w)
                })
            })
            .filter(|&(_, _, w)| w != 0.0)
            .collect();
        let mut d = Frame::zeros(rows, det_cols);
        // detector rows in parallel, each summing in band and tap order
        d.as_mut_slice()
            .par_chunks_mut(det_cols)
            .with_min_len(8)
            .enumerate()
            .for_each(|(yr, drow)| {
                for &(k, tap, w) in &taps {
                    let Some(r) = shifted_row(yr, -tap.row, rows) else {
                        continue;
                    };
                    let c0 = tap.col as usize;
                    let out = &mut drow[c0..c0 + cols];
                    for ((o, &m), &m2) in out
                        .iter_mut()
                        .zip(self.mask_slice(k, r, yr, c0))
                        .zip(other.mask_slice(k, r, yr, c0))
                    {
                        *o += w * m * m2;
                    }
                }
            });
        d
    }
}

/// y = A x of an operator taking (bands, rows, cols) cubes of `cube_shape`
/// to `measurement_shape` frames, a cube of another shape refused by name.
pub(crate) fn checked_forward(
    op: &dyn LinearOperator,
    cube_shape: (usize, usize, usize),
    (rows, cols): (usize, usize),
    cube: &Cube,
) -> Result<Measurement> {
    if cube.shape() != cube_shape {
        let (l, h, w) = cube_shape;
        let (cl, ch, cw) = cube.shape();
        return Err(shape_error(
            "scene cube (bands, rows, cols)",
            format!("({cl}, {ch}, {cw})"),
            format!("({l}, {h}, {w}) to match the {h}×{w} mask and {l} bands"),
        ));
    }
    let mut y = Frame::zeros(rows, cols);
    op.apply(cube.as_slice(), y.as_mut_slice());
    Ok(y)
}

/// A cube read one row at a time by [`CassiOperator::apply_rows`].
pub(crate) trait CubeRows: Sync {
    /// A thread's buffers for making rows.
    type Scratch: Default + Send;
    /// Row `r` of band `k` (cols long), borrowed or made in `scratch`.
    fn row<'a>(&'a self, k: usize, r: usize, scratch: &'a mut Self::Scratch) -> &'a [f32];
}

/// A stored cube (bands × rows × cols).
struct StoredRows<'x> {
    x: &'x [f32],
    rows: usize,
    cols: usize,
}

impl CubeRows for StoredRows<'_> {
    type Scratch = ();
    #[inline]
    fn row<'a>(&'a self, k: usize, r: usize, _: &'a mut ()) -> &'a [f32] {
        let at = (k * self.rows + r) * self.cols;
        &self.x[at..at + self.cols]
    }
}

/// Row `r + offset` if it lies on the detector.
#[inline]
fn shifted_row(r: usize, offset: i32, rows: usize) -> Option<usize> {
    let yr = r as i64 + offset as i64;
    (yr >= 0 && (yr as usize) < rows).then_some(yr as usize)
}

/// Mask transmissions and tap weights are ≥ 0.
impl NonNegativeOperator for CassiOperator {}

impl LinearOperator for CassiOperator {
    fn domain_len(&self) -> usize {
        let (l, h, w) = self.cube_shape();
        l * h * w
    }

    fn range_len(&self) -> usize {
        let (h, wd) = self.measurement_shape();
        h * wd
    }

    fn diag_aat(&self) -> Option<Vec<f32>> {
        Some(CassiOperator::diag_aat(self).into_vec())
    }

    /// diag(A Aᵀ), [`NormaliserKind::Exact`], when every band lands on one
    /// detector pixel per cube pixel (the rounded model, or subpixel offsets
    /// that happen to be integers): each column of A has one non-zero, so
    /// A Aᵀ is diagonal. Otherwise (split taps, A Aᵀ couples neighbouring
    /// detector pixels) the row sums Φ = A Aᵀ 𝟙 = A (Aᵀ 𝟙), one adjoint and
    /// one apply: A ≥ 0 (mask and tap weights), so Φ − A Aᵀ is diagonally
    /// dominant with a non-negative diagonal and Φ ⪰ A Aᵀ (Gershgorin), a
    /// [`NormaliserKind::Majoriser`]. (For the exact case A Aᵀ 𝟙 would be
    /// the same diagonal up to summation order; diag(A Aᵀ) keeps rounded
    /// reconstructions bit-identical to before.)
    fn aat_normaliser(&self) -> Option<AatNormaliser> {
        let exact = (0..self.bands()).all(|k| self.dispersion.taps(k).len() <= 1);
        if exact {
            return Some(AatNormaliser {
                phi: CassiOperator::diag_aat(self).into_vec(),
                kind: NormaliserKind::Exact,
            });
        }
        Some(row_sum_majoriser(self))
    }

    fn apply(&self, x: &[f32], y: &mut [f32]) {
        assert_eq!(x.len(), self.domain_len(), "CassiOperator::apply: x length");
        let (_, rows, cols) = self.cube_shape();
        self.apply_rows(&StoredRows { x, rows, cols }, y);
    }

    fn adjoint(&self, y: &[f32], x: &mut [f32]) {
        let (_, rows, cols) = self.cube_shape();
        assert_eq!(
            y.len(),
            self.range_len(),
            "CassiOperator::adjoint: y length"
        );
        assert_eq!(
            x.len(),
            self.domain_len(),
            "CassiOperator::adjoint: x length"
        );
        let simd = Simd::detect(false);
        x.par_chunks_mut(cols)
            .with_min_len(16)
            .enumerate()
            .for_each(|(i, xrow)| self.adjoint_row(simd, y, i / rows, i % rows, xrow));
    }
}

impl CassiOperator {
    /// y = A x for a cube given row by row (`x`): the same products as
    /// [`LinearOperator::apply`], for a cube that is cheaper to make a row
    /// at a time than to store (the scene fit's coarse scene).
    pub(crate) fn apply_rows<R: CubeRows>(&self, x: &R, y: &mut [f32]) {
        let (bands, rows, cols) = self.cube_shape();
        assert_eq!(y.len(), self.range_len(), "CassiOperator::apply: y length");
        // Each detector row gathers from the cube rows that land on it, so rows
        // are independent: no atomics, same result for any thread count.
        let simd = Simd::detect(false);

        let det_cols = self.det_cols;
        if let Some(l) = self.landing.as_ref().filter(|l| l.stored.get().is_none()) {
            // the band masks row by row, never stored (see `Landing`); the
            // same values as stored ones, so the same y
            let width = l.masks.width();
            y.par_chunks_mut(det_cols)
                .with_min_len(8)
                .enumerate()
                .for_each_init(
                    || (vec![0.0f32; width], R::Scratch::default()),
                    |(buf, scratch), (yr, yrow)| {
                        yrow.fill(0.0);
                        for k in 0..bands {
                            let lo = l.masks.first_col(k);
                            let mut filled = false;
                            for run in tap_runs(self.dispersion.taps(k)) {
                                let tap = run.first;
                                let Some(r) = shifted_row(yr, -tap.row, rows) else {
                                    continue;
                                };
                                if !filled {
                                    let n = width.min(det_cols - lo);
                                    l.masks.row(simd, k, yr, &mut buf[..n]);
                                    filled = true;
                                }
                                let c0 = tap.col as usize;
                                let span = cols + run.next.is_some() as usize;
                                let mrow = &buf[c0 - lo..c0 - lo + span];
                                let xrow = x.row(k, r, scratch);
                                accumulate_landed(simd, &mut yrow[c0..c0 + span], xrow, mrow, run);
                            }
                        }
                    },
                );
            return;
        }
        y.par_chunks_mut(det_cols)
            .with_min_len(8)
            .enumerate()
            .for_each_init(R::Scratch::default, |scratch, (yr, yrow)| {
                yrow.fill(0.0);
                for k in 0..bands {
                    if self.landing.is_some() {
                        for run in tap_runs(self.dispersion.taps(k)) {
                            let tap = run.first;
                            let Some(r) = shifted_row(yr, -tap.row, rows) else {
                                continue;
                            };
                            let xrow = x.row(k, r, scratch);
                            let c0 = tap.col as usize;
                            let span = cols + run.next.is_some() as usize;
                            let mrow = self.landed_mask(k, yr, c0, span);
                            accumulate_landed(simd, &mut yrow[c0..c0 + span], xrow, mrow, run);
                        }
                        continue;
                    }
                    for tap in self.dispersion.taps(k) {
                        // source row r with r + tap.row = yr
                        let Some(r) = shifted_row(yr, -tap.row, rows) else {
                            continue;
                        };
                        let xrow = x.row(k, r, scratch);
                        let c0 = tap.col as usize;
                        let mrow = self.mask_slice(k, r, yr, c0);
                        accumulate(simd, &mut yrow[c0..c0 + cols], xrow, mrow, tap.weight);
                    }
                }
            });
    }

    /// Row `r` of band `k` of Aᵀ `y` into `xrow`: what
    /// [`LinearOperator::adjoint`] writes there, for callers that use the
    /// rows as they come (the proxy's prior step) instead of a whole cube.
    #[inline]
    pub(crate) fn adjoint_row(&self, simd: Simd, y: &[f32], k: usize, r: usize, xrow: &mut [f32]) {
        let (rows, cols) = (self.mask.rows(), self.mask.cols());
        xrow.fill(0.0);
        if self.landing.is_some() {
            // the mask differs per tap: multiply before summing
            for run in tap_runs(self.dispersion.taps(k)) {
                let tap = run.first;
                let Some(yr) = shifted_row(r, tap.row, rows) else {
                    continue;
                };
                let c0 = tap.col as usize;
                let span = cols + run.next.is_some() as usize;
                let src = &y[yr * self.det_cols + c0..yr * self.det_cols + c0 + span];
                let m = self.landed_mask(k, yr, c0, span);
                match run.next {
                    None => weighted_coded_row(simd, xrow, src, m, tap.weight),
                    Some(next) => {
                        weighted_coded_pair_adjoint(simd, xrow, src, m, tap.weight, next.weight)
                    }
                }
            }
            return;
        }
        for tap in self.dispersion.taps(k) {
            let Some(yr) = shifted_row(r, tap.row, rows) else {
                continue;
            };
            let c0 = yr * self.det_cols + tap.col as usize;
            let src = &y[c0..c0 + cols];
            if tap.weight == 1.0 {
                add_row(simd, xrow, src);
            } else {
                weighted_add_row(simd, xrow, src, tap.weight);
            }
        }
        mask_row(simd, xrow, self.mask.row(r));
    }
}

/// out += weight · (m ⊙ x), exactly m ⊙ x when the weight is 1.
#[inline]
fn accumulate(simd: Simd, out: &mut [f32], x: &[f32], m: &[f32], weight: f32) {
    if weight == 1.0 {
        coded_row(simd, out, x, m);
    } else {
        weighted_coded_row(simd, out, x, m, weight);
    }
}

/// A band's taps taken in order, two at a time where the second lands one
/// column right of the first on the same row (a subpixel split): the
/// dispersed-mask model's pair reads its mask row and writes its detector
/// row once, for the same sums in the same order as tap by tap.
#[derive(Clone, Copy)]
struct TapRun<'t> {
    first: &'t Tap,
    next: Option<&'t Tap>,
}

fn tap_runs(taps: &[Tap]) -> impl Iterator<Item = TapRun<'_>> {
    let mut t = 0;
    std::iter::from_fn(move || {
        let first = taps.get(t)?;
        let next = taps
            .get(t + 1)
            .filter(|n| n.row == first.row && n.col == first.col + 1);
        t += 1 + next.is_some() as usize;
        Some(TapRun { first, next })
    })
}

/// out += (band mask m) ⊙ (the run's taps of x): `out` and `m` span the
/// run's columns (one more than x for a pair).
#[inline]
fn accumulate_landed(simd: Simd, out: &mut [f32], x: &[f32], m: &[f32], run: TapRun<'_>) {
    match run.next {
        None => accumulate(simd, out, x, m, run.first.weight),
        Some(next) => weighted_coded_pair(simd, out, x, m, run.first.weight, next.weight),
    }
}

// The operator's row loops, compiled for the baseline target and for AVX
// (picked at run time): the same arithmetic per element in either copy, so
// results do not depend on the CPU.
kernel!(coded_row, coded_row_port, coded_row_avx,
(out: &mut [f32], x: &[f32], m: &[f32]) -> () = {
    for ((o, &xv), &mv) in out.iter_mut().zip(x).zip(m) {
        *o += mv * xv;
    }
});
kernel!(weighted_coded_row, weighted_coded_row_port, weighted_coded_row_avx,
(out: &mut [f32], x: &[f32], m: &[f32], w: f32) -> () = {
    for ((o, &xv), &mv) in out.iter_mut().zip(x).zip(m) {
        *o += w * (mv * xv);
    }
});
// A subpixel pair, tap by tap's arithmetic per element in the same order:
// out[i] += w0·(m[i]·x[i]), then out[i] += w1·(m[i]·x[i−1]) (out and m one
// longer than x).
kernel!(weighted_coded_pair, weighted_coded_pair_port, weighted_coded_pair_avx,
(out: &mut [f32], x: &[f32], m: &[f32], w0: f32, w1: f32) -> () = {
    let n = x.len();
    if n == 0 {
        return;
    }
    out[0] += w0 * (m[0] * x[0]);
    for (((o, &mv), &x0), &x1) in out[1..n]
        .iter_mut()
        .zip(&m[1..n])
        .zip(&x[1..])
        .zip(&x[..n - 1])
    {
        let t = *o + w0 * (mv * x0);
        *o = t + w1 * (mv * x1);
    }
    out[n] += w1 * (m[n] * x[n - 1]);
});
// Its adjoint, tap by tap's order: out[i] += w0·(m[i]·y[i]), then
// out[i] += w1·(m[i+1]·y[i+1]) (y and m one longer than out).
kernel!(weighted_coded_pair_adjoint, weighted_coded_pair_adjoint_port,
weighted_coded_pair_adjoint_avx,
(out: &mut [f32], y: &[f32], m: &[f32], w0: f32, w1: f32) -> () = {
    for (((o, (&m0, &m1)), &y0), &y1) in out
        .iter_mut()
        .zip(m.iter().zip(&m[1..]))
        .zip(y)
        .zip(&y[1..])
    {
        let t = *o + w0 * (m0 * y0);
        *o = t + w1 * (m1 * y1);
    }
});
kernel!(add_row, add_row_port, add_row_avx,
(out: &mut [f32], src: &[f32]) -> () = {
    for (o, &v) in out.iter_mut().zip(src) {
        *o += v;
    }
});
kernel!(pub(crate) weighted_add_row, weighted_add_row_port, weighted_add_row_avx,
(out: &mut [f32], src: &[f32], w: f32) -> () = {
    for (o, &v) in out.iter_mut().zip(src) {
        *o += w * v;
    }
});
kernel!(mask_row, mask_row_port, mask_row_avx,
(out: &mut [f32], m: &[f32]) -> () = {
    for (o, &mv) in out.iter_mut().zip(m) {
        *o *= mv;
    }
});

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linop::adjoint_mismatch;
    use crate::params::DispersionParams;
    use crate::synth::uniform_grey_mask;

    #[test]
    fn adjoint_identity_holds_for_both_models_and_many_geometries() {
        let cases = [
            (28, 2.0, 0.0, 17, 23),
            (28, 2.04, 0.5, 16, 16),
            (8, 1.37, -3.0, 12, 9),
            (5, 3.0, 20.0, 30, 11),
            (1, 2.0, 0.0, 4, 4),
            (3, 0.6, 44.0, 6, 8),
        ];
        for (bands, a1, alpha, rows, cols) in cases {
            for model in [DispersionModel::Rounded, DispersionModel::Subpixel] {
                let d = Dispersion::new(
                    bands,
                    DispersionParams {
                        a1,
                        alpha_deg: alpha,
                        a2: 0.0,
                    },
                    model,
                )
                .unwrap();
                let op = CassiOperator::new(uniform_grey_mask(rows, cols, 5), d).unwrap();
                let e = adjoint_mismatch(&op, 9);
                assert!(
                    e < 1e-5,
                    "{model:?} a1={a1} α={alpha}: adjoint mismatch {e}"
                );
            }
        }
    }

    /// diag(A Aᵀ)_jj = ‖Aᵀ e_j‖² for every detector pixel j (`what` names
    /// the case).
    fn assert_diag_is_column_norms(op: &CassiOperator, what: &dyn std::fmt::Debug) {
        let diag = op.diag_aat();
        let mut unit = vec![0.0f32; op.range_len()];
        let mut col = vec![0.0f32; op.domain_len()];
        for j in 0..op.range_len() {
            unit.fill(0.0);
            unit[j] = 1.0;
            op.adjoint(&unit, &mut col);
            let want: f32 = col.iter().map(|v| v * v).sum();
            assert!((diag.as_slice()[j] - want).abs() < 1e-5, "{what:?} j={j}");
        }
    }

    /// The dispersed-mask model: exact adjoint and diag(A Aᵀ) for poses and
    /// dispersions with fractional offsets.
    #[test]
    fn dispersed_mask_adjoint_and_diagonal_hold() {
        let nominal = uniform_grey_mask(9, 11, 4);
        for (dx, dy, theta, a1, alpha) in [
            (0.3, -0.6, 0.4, 2.07, 0.8),
            (-1.5, 0.0, 0.0, 1.6, -3.0),
            (0.0, 0.0, 0.0, 2.0, 0.0),
        ] {
            let m = Mismatch {
                dx,
                dy,
                theta_deg: theta,
                a1,
                alpha_deg: alpha,
                ..Mismatch::nominal(2.0)
            };
            let op = CassiOperator::with_mismatch(&nominal, 5, &m, DispersionModel::DispersedMask)
                .unwrap();
            let e = adjoint_mismatch(&op, 3);
            assert!(e < 1e-5, "{m:?}: adjoint mismatch {e}");
            assert_diag_is_column_norms(&op, &m);
        }
    }

    /// The band masks computed row by row inside a forward (a candidate
    /// applied once) and stored (after an adjoint: an iterative solver) give
    /// the same measurement, bit for bit.
    #[test]
    fn dispersed_mask_forward_is_the_same_with_stored_band_masks() {
        let nominal = uniform_grey_mask(12, 15, 8);
        let m = Mismatch {
            dx: -0.4,
            dy: 0.7,
            theta_deg: 0.6,
            a1: 1.97,
            alpha_deg: -0.9,
            ..Mismatch::nominal(2.0)
        };
        let op =
            CassiOperator::with_mismatch(&nominal, 6, &m, DispersionModel::DispersedMask).unwrap();
        let x = Cube::from_vec(
            6,
            12,
            15,
            (0..6 * 12 * 15)
                .map(|i| ((i * 37) % 11) as f32 / 10.0)
                .collect(),
        )
        .unwrap();
        let on_the_fly = op.forward(&x).unwrap();
        assert!(op.landing.as_ref().unwrap().stored.get().is_none());
        let _ = op.back_project(&on_the_fly).unwrap();
        assert!(op.landing.as_ref().unwrap().stored.get().is_some());
        assert_eq!(op.forward(&x).unwrap(), on_the_fly);
    }

    /// The dispersed-mask model's subpixel pairs, taken together, give the
    /// bits of the tap-by-tap loop (forward on the fly and stored, and the
    /// adjoint), with two taps a band (α = 0) and four (α ≠ 0).
    #[test]
    fn dispersed_mask_pairs_give_the_bits_of_tap_by_tap_sums() {
        let nominal = uniform_grey_mask(13, 21, 9);
        let (bands, rows, cols) = (7, 13, 21);
        for alpha in [0.0, 1.7, -0.6] {
            let m = Mismatch {
                dx: 0.37,
                dy: -0.55,
                theta_deg: 0.3,
                a1: 2.013,
                alpha_deg: alpha,
                ..Mismatch::nominal(2.0)
            };
            let op =
                CassiOperator::with_mismatch(&nominal, bands, &m, DispersionModel::DispersedMask)
                    .unwrap();
            // band 0 lands whole; the others split two or four ways
            let taps: Vec<usize> = (0..bands).map(|k| op.dispersion.taps(k).len()).collect();
            assert!(
                taps[1..]
                    .iter()
                    .all(|&n| n == if alpha == 0.0 { 2 } else { 4 })
            );
            let x: Vec<f32> = (0..bands * rows * cols)
                .map(|i| ((i * 7919) % 1013) as f32 / 1013.0 + 0.1)
                .collect();
            let (_, det_cols) = op.measurement_shape();
            let on_the_fly = op
                .forward(&Cube::from_vec(bands, rows, cols, x.clone()).unwrap())
                .unwrap();
            let y = on_the_fly.as_slice().to_vec();
            let mut back = vec![0.0f32; x.len()];
            op.adjoint(&y, &mut back);
            let stored = op
                .forward(&Cube::from_vec(bands, rows, cols, x.clone()).unwrap())
                .unwrap();
            // the reference: each tap alone, in band and tap order
            let mut want_y = vec![0.0f32; rows * det_cols];
            let mut want_back = vec![0.0f32; x.len()];
            for k in 0..bands {
                for tap in op.dispersion.taps(k) {
                    let c0 = tap.col as usize;
                    for yr in 0..rows {
                        let Some(r) = shifted_row(yr, -tap.row, rows) else {
                            continue;
                        };
                        let mrow = op.landed_mask(k, yr, c0, cols);
                        for i in 0..cols {
                            let o = &mut want_y[yr * det_cols + c0 + i];
                            *o += tap.weight * (mrow[i] * x[(k * rows + r) * cols + i]);
                        }
                    }
                }
            }
            for k in 0..bands {
                for r in 0..rows {
                    for tap in op.dispersion.taps(k) {
                        let Some(yr) = shifted_row(r, tap.row, rows) else {
                            continue;
                        };
                        let c0 = tap.col as usize;
                        let mrow = op.landed_mask(k, yr, c0, cols);
                        for i in 0..cols {
                            let o = &mut want_back[(k * rows + r) * cols + i];
                            *o += tap.weight * (mrow[i] * y[yr * det_cols + c0 + i]);
                        }
                    }
                }
            }
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&y), bits(&want_y), "α {alpha}: forward on the fly");
            assert_eq!(
                bits(stored.as_slice()),
                bits(&want_y),
                "α {alpha}: forward stored"
            );
            assert_eq!(bits(&back), bits(&want_back), "α {alpha}: adjoint");
        }
    }

    /// Where every offset is whole the two subpixel models are one operator;
    /// a fractional offset makes the subpixel model interpolate the mask a
    /// second time, which the dispersed-mask model does not: one open mask
    /// pixel moved half a pixel by the pose and half a pixel by band 1's
    /// dispersion lands whole on the next pixel, not spread over three.
    #[test]
    fn dispersed_mask_samples_the_mask_once_where_the_band_lands() {
        let nominal = uniform_grey_mask(8, 10, 6);
        let whole = Mismatch {
            dx: 1.0,
            dy: -2.0,
            a1: 3.0,
            ..Mismatch::nominal(2.0)
        };
        let a =
            CassiOperator::with_mismatch(&nominal, 4, &whole, DispersionModel::Subpixel).unwrap();
        let b = CassiOperator::with_mismatch(&nominal, 4, &whole, DispersionModel::DispersedMask)
            .unwrap();
        let x = Cube::from_vec(4, 8, 10, (0..320).map(|i| (i % 7) as f32 / 6.0).collect()).unwrap();
        assert_eq!(a.forward(&x).unwrap(), b.forward(&x).unwrap());

        let mut mask = Frame::zeros(5, 5);
        mask.set(2, 1, 1.0);
        let half = Mismatch {
            dx: 0.5,
            a1: 0.5,
            ..Mismatch::nominal(2.0)
        };
        let mut x = Cube::zeros(2, 5, 5);
        for v in x.band_mut(1) {
            *v = 1.0;
        }
        let y = |model| {
            CassiOperator::with_mismatch(&mask, 2, &half, model)
                .unwrap()
                .forward(&x)
                .unwrap()
        };
        let (single, double) = (
            y(DispersionModel::DispersedMask),
            y(DispersionModel::Subpixel),
        );
        // pose 0.5 + band 1's 0.5: the open square now covers column 2 exactly
        assert!((single.get(2, 2) - 1.0).abs() < 1e-6, "{single:?}");
        assert_eq!(single.as_slice().iter().filter(|&&v| v > 1e-6).count(), 1);
        // the subpixel model spreads it 1/4, 1/2, 1/4 over columns 1–3
        assert!((double.get(2, 2) - 0.5).abs() < 1e-6, "{double:?}");
        assert!((double.get(2, 1) - 0.25).abs() < 1e-6, "{double:?}");
        assert!((double.get(2, 3) - 0.25).abs() < 1e-6, "{double:?}");
    }

    #[test]
    fn one_pixel_one_band_lands_at_its_offset() {
        // band k of a pixel at (r, c) reaches detector column c + 2k (stride 2)
        let mut mask = Frame::zeros(4, 5);
        mask.set(1, 2, 1.0);
        let op = CassiOperator::new(
            mask,
            Dispersion::nominal(3, 2.0, DispersionModel::Rounded).unwrap(),
        )
        .unwrap();
        assert_eq!(op.measurement_shape(), (4, 5 + 4));
        let mut cube = Cube::zeros(3, 4, 5);
        cube.set(2, 1, 2, 0.5);
        cube.set(0, 1, 2, 0.25);
        cube.set(1, 0, 0, 7.0); // masked out (mask is 0 there)
        let y = op.forward(&cube).unwrap();
        assert_eq!(y.get(1, 2), 0.25);
        assert_eq!(y.get(1, 6), 0.5);
        assert_eq!(y.as_slice().iter().sum::<f32>(), 0.75);
    }

    #[test]
    fn tilted_dispersion_moves_light_down_and_loses_it_past_the_last_row() {
        // α = 45°, a1 = √2: band 1 moves (1 col, 1 row)
        let d = Dispersion::new(
            2,
            DispersionParams {
                a1: 2f64.sqrt(),
                alpha_deg: 45.0,
                a2: 0.0,
            },
            DispersionModel::Rounded,
        )
        .unwrap();
        let op = CassiOperator::new(Frame::from_vec(3, 3, vec![1.0; 9]).unwrap(), d).unwrap();
        let mut cube = Cube::zeros(2, 3, 3);
        cube.set(1, 0, 0, 1.0);
        cube.set(1, 2, 0, 1.0); // would land on row 3: off the detector
        let y = op.forward(&cube).unwrap();
        assert_eq!(y.get(1, 1), 1.0);
        assert_eq!(y.as_slice().iter().sum::<f32>(), 1.0);
    }

    #[test]
    fn diag_aat_matches_explicit_columns() {
        for model in [DispersionModel::Rounded, DispersionModel::Subpixel] {
            let d = Dispersion::new(
                4,
                DispersionParams {
                    a1: 1.3,
                    alpha_deg: 7.0,
                    a2: 0.0,
                },
                model,
            )
            .unwrap();
            let op = CassiOperator::new(uniform_grey_mask(5, 6, 2), d).unwrap();
            assert_diag_is_column_norms(&op, &model);
        }
    }

    #[test]
    fn shape_and_range_errors_are_reported() {
        let op = CassiOperator::new(
            Frame::zeros(4, 4),
            Dispersion::nominal(2, 2.0, DispersionModel::Rounded).unwrap(),
        )
        .unwrap();
        let e = op.forward(&Cube::zeros(2, 5, 4)).unwrap_err().to_string();
        assert!(e.contains("(2, 5, 4)") && e.contains("(2, 4, 4)"), "{e}");
        let e = op
            .back_project(&Frame::zeros(4, 4))
            .unwrap_err()
            .to_string();
        assert!(e.contains("4×4") && e.contains("4×6"), "{e}");
        let bad = Frame::from_vec(1, 2, vec![0.0, 255.0]).unwrap();
        let e = CassiOperator::new(
            bad,
            Dispersion::nominal(2, 2.0, DispersionModel::Rounded).unwrap(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("255"), "{e}");
    }

    #[test]
    fn mismatch_operator_uses_the_warped_mask() {
        let mut mask = Frame::zeros(6, 6);
        mask.set(2, 2, 1.0);
        let m = Mismatch {
            dx: 1.0,
            dy: 2.0,
            theta_deg: 0.0,
            a1: 2.0,
            alpha_deg: 0.0,
            ..Mismatch::nominal(2.0)
        };
        let op = CassiOperator::with_mismatch(&mask, 3, &m, DispersionModel::Rounded).unwrap();
        assert_eq!(op.mask().get(4, 3), 1.0);
    }

    /// The dispersed-mask operator warps its mask-grid mask only when asked
    /// (its products read the band masks), and that mask is the same as
    /// every other model's.
    #[test]
    fn every_tapped_model_reports_the_same_warped_mask() {
        let nominal = crate::synth::random_binary_mask(12, 14, 0.5, 4).unwrap();
        let m = Mismatch {
            dx: 0.4,
            dy: -1.3,
            theta_deg: 0.7,
            ..Mismatch::nominal(2.0)
        };
        let want = warp_mask(&nominal, &m.pose());
        for model in DispersionModel::TAPPED {
            let op = CassiOperator::with_mismatch(&nominal, 3, &m, model).unwrap();
            assert_eq!(op.mask().as_slice(), want.as_slice(), "{model:?}");
            assert_eq!(op.mask().shape(), (12, 14));
        }
    }
}
