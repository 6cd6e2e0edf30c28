//! MST's mask-guided mechanism (`mm`): turns the (shifted) coded-aperture
//! mask into a per-channel modulation of V, then shifts the dispersion back
//! so it lines up with the h×h feature grid.

use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;
use crate::ops::activation::sigmoid_gate_in_place;
use crate::ops::conv::Conv2d;
use crate::ops::depthwise::DepthwiseConv2d;

pub(crate) struct MaskGuide {
    conv1: Conv2d,
    conv2: Conv2d,
    depth_conv: DepthwiseConv2d,
}

impl MaskGuide {
    pub fn load(w: &mut WeightLoader, name: &str, c: usize) -> Self {
        Self {
            conv1: Conv2d::load(w, &format!("{name}.conv1"), c, c, 1, true),
            conv2: Conv2d::load(w, &format!("{name}.conv2"), c, c, 1, true),
            depth_conv: DepthwiseConv2d::load(w, &format!("{name}.depth_conv"), c, 5, true),
        }
    }

    /// mask (C, h, W′) → emb (C, h, h): m1 = conv1(mask);
    /// m2 = m1 ⊙ sigmoid(depth_conv(conv2(m1))) + m1; then shift back.
    pub fn forward(&self, mask: &FeatureMap) -> FeatureMap {
        let m1 = self.conv1.forward(mask);
        let mut a = self.depth_conv.forward(&self.conv2.forward(&m1));
        sigmoid_gate_in_place(&mut a.data, &m1.data);
        shift_back(&a)
    }
}

/// emb[c, r, j] = m[c, r, j + ⌊2c / D²⌋] for j < h, with D = 256 / h: the
/// reference's `shift_back` (step 2 at 256², scaled by each down-sampling).
pub(crate) fn shift_back(m: &FeatureMap) -> FeatureMap {
    let h = m.h;
    let d = 256 / h;
    let mut out = FeatureMap::for_overwrite(m.c, h, h);
    for c in 0..m.c {
        let off = 2 * c / (d * d);
        assert!(off + h <= m.w, "mask too narrow for the shift-back");
        for r in 0..h {
            let src = &m.data[(c * m.h + r) * m.w + off..][..h];
            out.data[(c * h + r) * h..][..h].copy_from_slice(src);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_back_offsets_follow_the_down_sampling() {
        // 128 rows (D = 2): channel c starts at column ⌊c/2⌋.
        let (c, h, w) = (4, 128, 155);
        let m = FeatureMap::from_vec(c, h, w, (0..c * h * w).map(|i| (i % w) as f32).collect());
        let e = shift_back(&m);
        assert_eq!((e.c, e.h, e.w), (4, 128, 128));
        for ch in 0..c {
            assert_eq!(e.data[(ch * h + 5) * h], (ch / 2) as f32, "channel {ch}");
        }
        // 256 rows (D = 1): offset 2c.
        let m = FeatureMap::from_vec(
            3,
            256,
            310,
            (0..3 * 256 * 310).map(|i| (i % 310) as f32).collect(),
        );
        let e = shift_back(&m);
        assert_eq!(e.data[2 * 256 * 256 + 7], 11.0);
    }
}
