//! Element-wise activations and softmax, as PyTorch defines them.

use rayon::prelude::*;

/// Elements per parallel chunk of element-wise maps: big enough that rayon's
/// overhead vanishes, small enough to share work on 2 cores.
const CHUNK: usize = 1 << 15;

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
    x.par_chunks_mut(CHUNK).for_each(gelu_chunk);
}

super::simd::avx2_dispatch! {
    fn gelu_chunk(x: &mut [f32]) {
        for v in x {
            *v = gelu_value(*v);
        }
    }
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

#[inline]
pub(crate) fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
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
