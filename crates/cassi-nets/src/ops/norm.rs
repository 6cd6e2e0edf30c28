//! Normalisations: LayerNorm over the channels of each pixel (MST's PreNorm
//! on channel-first maps) and BatchNorm in eval mode (HDNet).

use rayon::prelude::*;

use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;

pub(crate) struct LayerNormChannels {
    weight: Vec<f32>,
    bias: Vec<f32>,
    eps: f32,
}

impl LayerNormChannels {
    pub fn load(w: &mut WeightLoader, name: &str, channels: usize) -> Self {
        Self {
            weight: w.take(&format!("{name}.weight"), &[channels]).into_data(),
            bias: w.take(&format!("{name}.bias"), &[channels]).into_data(),
            eps: 1e-5,
        }
    }

    /// y[c, p] = (x[c, p] − μ_p) / √(σ²_p + eps) · weight[c] + bias[c], with μ, σ²
    /// (biased) over c. Stats per pixel chunk, then the map per channel.
    pub fn forward(&self, x: &FeatureMap) -> FeatureMap {
        let (c, n) = (x.c, x.plane());
        assert_eq!(c, self.weight.len(), "layer norm channels");
        let mut mean = vec![0.0f32; n];
        let mut rstd = vec![0.0f32; n];
        const PIX: usize = 4096;
        mean.par_chunks_mut(PIX)
            .zip(rstd.par_chunks_mut(PIX))
            .enumerate()
            .for_each(|(t, (m, r))| {
                let p0 = t * PIX;
                for ch in 0..c {
                    let row = &x.data[ch * n + p0..][..m.len()];
                    m.iter_mut().zip(row).for_each(|(a, v)| *a += v);
                }
                m.iter_mut().for_each(|a| *a /= c as f32);
                for ch in 0..c {
                    let row = &x.data[ch * n + p0..][..m.len()];
                    r.iter_mut()
                        .zip(row)
                        .zip(m.iter())
                        .for_each(|((a, v), mu)| {
                            let d = v - mu;
                            *a += d * d;
                        });
                }
                r.iter_mut()
                    .for_each(|a| *a = 1.0 / (*a / c as f32 + self.eps).sqrt());
            });
        let mut out = FeatureMap::for_overwrite(c, x.h, x.w);
        out.data
            .par_chunks_mut(n)
            .enumerate()
            .for_each(|(ch, dst)| {
                let (g, b) = (self.weight[ch], self.bias[ch]);
                let src = &x.data[ch * n..][..n];
                for (((d, v), mu), rs) in dst.iter_mut().zip(src).zip(&mean).zip(&rstd) {
                    *d = (v - mu) * rs * g + b;
                }
            });
        out
    }
}

/// BatchNorm2d in eval mode, folded to y = x·scale[c] + shift[c].
pub(crate) struct BatchNorm {
    scale: Vec<f32>,
    shift: Vec<f32>,
}

impl BatchNorm {
    pub fn load(w: &mut WeightLoader, name: &str, channels: usize) -> Self {
        let g = w.take(&format!("{name}.weight"), &[channels]).into_data();
        let b = w.take(&format!("{name}.bias"), &[channels]).into_data();
        let m = w
            .take(&format!("{name}.running_mean"), &[channels])
            .into_data();
        let v = w
            .take(&format!("{name}.running_var"), &[channels])
            .into_data();
        w.skip_buffer(&format!("{name}.num_batches_tracked"));
        // (x − m)/√(v + eps)·g + b, with the division folded in f64.
        let scale: Vec<f32> = (0..channels)
            .map(|c| (g[c] as f64 / (v[c] as f64 + 1e-5).sqrt()) as f32)
            .collect();
        let shift = (0..channels).map(|c| b[c] - m[c] * scale[c]).collect();
        Self { scale, shift }
    }

    pub fn apply_in_place(&self, x: &mut FeatureMap) {
        let n = x.plane();
        x.data.par_chunks_mut(n).enumerate().for_each(|(c, ch)| {
            let (s, t) = (self.scale[c], self.shift[c]);
            ch.iter_mut().for_each(|v| *v = *v * s + t);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_norm_normalises_each_pixel_over_channels() {
        let ln = LayerNormChannels {
            weight: vec![1.0, 2.0],
            bias: vec![0.0, 1.0],
            eps: 0.0,
        };
        // pixel 0: (1, 3) → (−1, 1); pixel 1: (5, 5) would divide by 0, so (2, 6) → (−1, 1).
        let x = FeatureMap::from_vec(2, 1, 2, vec![1.0, 2.0, 3.0, 6.0]);
        let y = ln.forward(&x);
        assert_eq!(y.data, vec![-1.0, -1.0, 3.0, 3.0]);
    }
}
