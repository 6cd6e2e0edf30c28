//! Element-wise activations and softmax, as PyTorch defines them.

use rayon::prelude::*;

use crate::fmap::ELEMENTWISE_CHUNK as CHUNK;

/// erf(x) in f32 by a rational minimax approximation (plain mul/add: `mul_add`
/// is a libm call unless the build targets FMA) on [−4, 4] (outside,
/// erf rounds to ±1 in f32). Only multiply/add/divide, so loops over it
/// vectorise — libm's erff was the bottleneck of MST's GELUs. Max abs error
/// against f64 erf is 4.4e-7 (7 f32 ulps of 1; checked below), so a GELU
/// moves by at most ~1.2e-6.
#[inline(always)]
pub(crate) fn erf(x: f32) -> f32 {
    let x = x.clamp(-4.0, 4.0);
    let x2 = x * x;
    let mut p = x2 * -2.726_142_3e-10 + 2.770_681_4e-8;
    p = x2 * p - 2.101_024e-6;
    p = x2 * p - 5.692_506_4e-5;
    p = x2 * p - 7.349_906_3e-4;
    p = x2 * p - 2.954_600_1e-3;
    p = x2 * p - 1.609_603_3e-2;
    p *= x;
    let mut q = x2 * -1.456_607_2e-5 - 2.133_740_6e-4;
    q = x2 * q - 1.682_827e-3;
    q = x2 * q - 7.373_329_2e-3;
    q = x2 * q - 1.426_473_9e-2;
    // Beyond 3.92, erf is 1 in f32 (1 − 3.5e-8 rounds up); the rational
    // form drifts to 1 − 3e-7 there, which a large GELU input would scale.
    if x.abs() >= 3.92 { x.signum() } else { p / q }
}

/// Exact (erf) GELU, PyTorch's default: 0.5·x·(1 + erf(x/√2)).
pub(crate) fn gelu_in_place(x: &mut [f32]) {
    x.par_chunks_mut(CHUNK).for_each(gelu_slice);
}

/// GELU over a slice, in this thread: eight lanes at a time with FMA where
/// the CPU has AVX2 + FMA (half the instructions of the plain mul/add
/// form; MST evaluates ~10⁸ GELUs per pass), else [`gelu_value`]. The two
/// differ by rounding only (tested within erf's 4.4e-7 accuracy).
pub(crate) fn gelu_slice(x: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has both features.
        unsafe { gelu_slice_fma(x) };
        return;
    }
    x.iter_mut().for_each(|v| *v = gelu_value(*v));
}

/// [`gelu_m256`] over a slice.
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn gelu_slice_fma(x: &mut [f32]) {
    use std::arch::x86_64::*;
    let mut chunks = x.chunks_exact_mut(8);
    for chunk in &mut chunks {
        // SAFETY: the chunk holds exactly 8 floats.
        unsafe {
            let v = _mm256_loadu_ps(chunk.as_ptr());
            _mm256_storeu_ps(chunk.as_mut_ptr(), gelu_m256(v));
        }
    }
    for v in chunks.into_remainder() {
        *v = gelu_value(*v);
    }
}

/// GELU of eight lanes: [`gelu_value`]'s formula (same erf coefficients)
/// with fused multiply-adds and a Newton-refined reciprocal for erf's
/// quotient (the division's throughput was half of a GELU loop's time).
/// NaN propagates.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub(crate) fn gelu_m256(v: std::arch::x86_64::__m256) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    let c = _mm256_set1_ps;
    // max(lo, z) / min(hi, z) return z when z is NaN, so NaN propagates.
    let z = _mm256_mul_ps(v, c(std::f32::consts::FRAC_1_SQRT_2));
    let z = _mm256_min_ps(c(4.0), _mm256_max_ps(c(-4.0), z));
    let z2 = _mm256_mul_ps(z, z);
    let mut p = _mm256_fmadd_ps(z2, c(-2.726_142_3e-10), c(2.770_681_4e-8));
    p = _mm256_fmadd_ps(z2, p, c(-2.101_024e-6));
    p = _mm256_fmadd_ps(z2, p, c(-5.692_506_4e-5));
    p = _mm256_fmadd_ps(z2, p, c(-7.349_906_3e-4));
    p = _mm256_fmadd_ps(z2, p, c(-2.954_600_1e-3));
    p = _mm256_fmadd_ps(z2, p, c(-1.609_603_3e-2));
    p = _mm256_mul_ps(p, z);
    let mut q = _mm256_fmadd_ps(z2, c(-1.456_607_2e-5), c(-2.133_740_6e-4));
    q = _mm256_fmadd_ps(z2, q, c(-1.682_827e-3));
    q = _mm256_fmadd_ps(z2, q, c(-7.373_329_2e-3));
    q = _mm256_fmadd_ps(z2, q, c(-1.426_473_9e-2));
    let r = _mm256_rcp_ps(q);
    let r = _mm256_mul_ps(r, _mm256_fnmadd_ps(q, r, c(2.0)));
    let erf = _mm256_mul_ps(p, r);
    // |z| ≥ 3.92: erf is ±1 in f32 (see `erf`).
    let sign = _mm256_and_ps(z, c(-0.0));
    let unit = _mm256_or_ps(sign, c(1.0));
    let abs = _mm256_andnot_ps(c(-0.0), z);
    let saturated = _mm256_cmp_ps::<_CMP_GE_OQ>(abs, c(3.92));
    let erf = _mm256_blendv_ps(erf, unit, saturated);
    _mm256_mul_ps(_mm256_mul_ps(c(0.5), v), _mm256_add_ps(c(1.0), erf))
}

#[inline(always)]
pub(crate) fn gelu_value(v: f32) -> f32 {
    0.5 * v * (1.0 + erf(v * std::f32::consts::FRAC_1_SQRT_2))
}

pub(crate) fn relu_in_place(x: &mut [f32]) {
    x.par_chunks_mut(CHUNK)
        .for_each(|c| c.iter_mut().for_each(|v| *v = v.max(0.0)));
}

pub(crate) fn leaky_relu_in_place(x: &mut [f32], slope: f32) {
    x.par_chunks_mut(CHUNK).for_each(|c| {
        c.iter_mut()
            .for_each(|v| *v = if *v >= 0.0 { *v } else { *v * slope })
    });
}

/// Logistic sigmoid through [`exp_poly`] (so loops over it vectorise).
#[inline(always)]
pub(crate) fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + exp_poly(-x))
}

/// eˣ in f32 from multiply/add and exponent bits only (vectorisable;
/// libm's expf is a call per element):
/// x = n·ln 2 + r with |r| ≤ ln 2 / 2 (Cody–Waite split of ln 2), e^r by
/// its degree-6 Taylor polynomial, times 2ⁿ. Relative error ≤ 2.5e-7
/// (tested); saturates to 0 below −87.3 and to f32::MAX·… above 88.7.
#[inline(always)]
pub(crate) fn exp_poly(x: f32) -> f32 {
    let x = x.clamp(-87.3, 88.7);
    // Round to nearest by the 1.5·2²³ trick (no libm call).
    const MAGIC: f32 = 12_582_912.0;
    let n = (x * std::f32::consts::LOG2_E + MAGIC) - MAGIC;
    let r = (x - n * 0.693_145_75) - n * 1.428_606_8e-6;
    let mut p = r * (1.0 / 720.0) + 1.0 / 120.0;
    p = r * p + 1.0 / 24.0;
    p = r * p + 1.0 / 6.0;
    p = r * p + 0.5;
    p = r * p + 1.0;
    p = r * p + 1.0;
    p * f32::from_bits(((n as i32 + 127) as u32) << 23)
}

/// a ← m ⊙ sigmoid(a) + m (MST's mask gate), in parallel chunks.
pub(crate) fn sigmoid_gate_in_place(a: &mut [f32], m: &[f32]) {
    assert_eq!(a.len(), m.len(), "gate sizes");
    a.par_chunks_mut(CHUNK)
        .zip(m.par_chunks(CHUNK))
        .for_each(|(a, m)| sigmoid_gate_chunk(a, m));
}

super::simd::avx2_dispatch! {
    fn sigmoid_gate_chunk(a: &mut [f32], m: &[f32]) {
        for (av, &mv) in a.iter_mut().zip(m) {
            *av = mv * sigmoid(*av) + mv;
        }
    }
}

/// Softmax over the whole slice (max-subtracted, as PyTorch), in f64
/// accumulation for long rows (HDNet softmaxes over all h·w pixels).
pub(crate) fn softmax_in_place(x: &mut [f32]) {
    let m = x.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mut sum = 0.0f64;
    for v in x.iter_mut() {
        *v = (*v - m).exp();
        sum += *v as f64;
    }
    let inv = (1.0 / sum) as f32;
    x.iter_mut().for_each(|v| *v *= inv);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erf_is_accurate_to_5e7() {
        let mut worst = 0.0f64;
        for i in -60_000..=60_000 {
            let x = i as f64 * 1e-4;
            let err = (erf(x as f32) as f64 - libm::erf(x)).abs();
            worst = worst.max(err);
        }
        assert!(worst < 5e-7, "max |erf error| = {worst:e}");
        assert_eq!(erf(10.0), erf(4.0));
        assert!((erf(4.0) - 1.0).abs() < 1e-7);
    }

    #[test]
    fn polynomial_exp_and_sigmoid_are_accurate() {
        let mut worst = 0.0f64;
        for i in -87_000..=88_000 {
            let x = i as f32 * 1e-3;
            let want = (x as f64).exp();
            worst = worst.max(((exp_poly(x) as f64 - want) / want).abs());
        }
        assert!(worst < 2.5e-7, "exp relative error {worst}");
        for x in [-200.0f32, -30.0, -1.0, 0.0, 0.5, 30.0, 200.0] {
            let want = 1.0 / (1.0 + (-(x as f64)).exp());
            assert!((sigmoid(x) as f64 - want).abs() < 2e-7, "sigmoid({x})");
        }
        assert!(exp_poly(f32::NAN).is_nan());
    }

    #[test]
    fn vector_gelu_matches_the_scalar_formula() {
        let mut x: Vec<f32> = (-4000..4000).map(|i| i as f32 * 0.00173).collect();
        x.extend([
            0.0,
            -0.0,
            5.5,
            -5.5,
            3.9,
            -3.95,
            1e-30,
            80.0,
            -80.0,
            f32::NAN,
        ]);
        let input = x.clone();
        let want: Vec<f32> = x.iter().map(|&v| gelu_value(v)).collect();
        gelu_slice(&mut x);
        for ((g, w), v) in x.iter().zip(&want).zip(&input) {
            if w.is_nan() {
                assert!(g.is_nan(), "NaN in, NaN out");
                continue;
            }
            // Each erf is within 4.4e-7 of the truth (near |z| = 3.9 the two
            // roundings differ most), scaled by v/2 in the GELU; plus the
            // rounding of the product.
            let tol = 4.4e-7 * v.abs() + 2.0 * f32::EPSILON * w.abs();
            assert!((g - w).abs() <= tol, "gelu({v}): {g} vs {w}");
        }
    }

    #[test]
    fn gelu_and_softmax_known_values() {
        let mut g = vec![0.0, 1.0, -1.0, 3.0];
        gelu_in_place(&mut g);
        let want = [0.0, 0.841_344_7, -0.158_655_26, 2.995_950_3];
        for (a, b) in g.iter().zip(want) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
        let mut s = vec![1.0, 2.0, 3.0];
        softmax_in_place(&mut s);
        let want = [0.090_030_57, 0.244_728_47, 0.665_240_94];
        for (a, b) in s.iter().zip(want) {
            assert!((a - b).abs() < 1e-7);
        }
    }
}
