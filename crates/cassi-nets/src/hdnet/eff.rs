//! HDNet's EFF (`body.17`): the 64 channels in 4 groups of 16, each
//! re-weighted by a DSC (a softmax over pixels of a pooled point-wise map).

use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;
use crate::ops::activation::{relu_in_place, softmax_in_place};
use crate::ops::conv::Conv2d;
use crate::ops::norm::BatchNorm;
use crate::ops::pool::max_pool_3x3;

/// Channels per EFF group (`nDiff`).
const GROUP: usize = 16;

struct Dsc {
    /// Depthwise 1×1 conv: a per-channel scale and bias.
    dws_scale: Vec<f32>,
    dws_bias: Vec<f32>,
    bn_dws: BatchNorm,
    conv_point: Conv2d,
    bn_point: BatchNorm,
}

impl Dsc {
    fn load(w: &mut WeightLoader, name: &str) -> Self {
        Self {
            dws_scale: w
                .take(&format!("{name}.conv_dws.weight"), &[GROUP, 1, 1, 1])
                .into_data(),
            dws_bias: w
                .take(&format!("{name}.conv_dws.bias"), &[GROUP])
                .into_data(),
            bn_dws: BatchNorm::load(w, &format!("{name}.bn_dws"), GROUP),
            conv_point: Conv2d::load(w, &format!("{name}.conv_point"), GROUP, 1, 1, true),
            bn_point: BatchNorm::load(w, &format!("{name}.bn_point"), 1),
        }
    }

    /// z (16, h, w) → s ⊙ z + z, s = softmax_pixels(relu(bn(conv_point(
    /// maxpool(relu(bn(dws(z)))))))) broadcast over the channels.
    fn forward(&self, z: &FeatureMap) -> FeatureMap {
        let n = z.plane();
        let mut t = z.clone();
        for (c, ch) in t.data.chunks_mut(n).enumerate() {
            let (s, b) = (self.dws_scale[c], self.dws_bias[c]);
            ch.iter_mut().for_each(|v| *v = *v * s + b);
        }
        self.bn_dws.apply_in_place(&mut t);
        relu_in_place(&mut t.data);
        let mut s = self.conv_point.forward(&max_pool_3x3(&t));
        self.bn_point.apply_in_place(&mut s);
        relu_in_place(&mut s.data);
        softmax_in_place(&mut s.data);
        let mut out = z.clone();
        for ch in out.data.chunks_mut(n) {
            ch.iter_mut()
                .zip(&s.data)
                .for_each(|(v, w)| *v = w * *v + *v);
        }
        out
    }
}

pub(crate) struct Eff {
    groups: Vec<Dsc>,
}

impl Eff {
    pub fn load(w: &mut WeightLoader, name: &str, c: usize) -> Self {
        let groups = (0..c / GROUP)
            .map(|i| Dsc::load(w, &format!("{name}.subspaces.{i}")))
            .collect();
        Self { groups }
    }

    pub fn forward(&self, x: &FeatureMap) -> FeatureMap {
        let len = GROUP * x.plane();
        let mut out = FeatureMap::for_overwrite(x.c, x.h, x.w);
        for (i, dsc) in self.groups.iter().enumerate() {
            let z = FeatureMap::from_slice(GROUP, x.h, x.w, &x.data[i * len..(i + 1) * len]);
            out.data[i * len..(i + 1) * len].copy_from_slice(&dsc.forward(&z).data);
        }
        out
    }
}
