//! HDNet's SDL attention (`body.16`): a channel gate G1 from a softmax-
//! pooled context and a pixel gate G2 from a channel-pooled query; out = G1 + G2.

use crate::checkpoint::WeightLoader;
use crate::fmap::FeatureMap;
use crate::ops::activation::{sigmoid, softmax_in_place};
use crate::ops::conv::Conv2d;

pub(crate) struct SdlAttention {
    conv_q_right: Conv2d,
    conv_v_right: Conv2d,
    conv_up: Conv2d,
    conv_q_left: Conv2d,
    conv_v_left: Conv2d,
}

impl SdlAttention {
    pub fn load(w: &mut WeightLoader, name: &str, c: usize) -> Self {
        let half = c / 2;
        let conv = |w: &mut WeightLoader, n: &str, cin, cout| {
            Conv2d::load(w, &format!("{name}.{n}"), cin, cout, 1, false)
        };
        Self {
            conv_q_right: conv(w, "conv_q_right", c, 1),
            conv_v_right: conv(w, "conv_v_right", c, half),
            conv_up: conv(w, "conv_up", half, c),
            conv_q_left: conv(w, "conv_q_left", c, half),
            conv_v_left: conv(w, "conv_v_left", c, half),
        }
    }

    pub fn forward(&self, x: &FeatureMap) -> FeatureMap {
        let n = x.plane();
        // G1 (`spatial_attention`): g = sigmoid(conv_up(vr · softmax(qr)ᵀ)), per channel.
        let vr = self.conv_v_right.forward(x);
        let mut p = self.conv_q_right.forward(x).into_data();
        softmax_in_place(&mut p);
        let context: Vec<f32> = (0..vr.c).map(|c| dot(vr.channel(c), &p)).collect();
        let gate = self
            .conv_up
            .forward(&FeatureMap::from_vec(vr.c, 1, 1, context));
        // G2 (`spectral_attention`): t = mean_pixels(conv_q_left x) · conv_v_left x,
        // then sigmoid(softmax(t)) per pixel.
        let gl = self.conv_q_left.forward(x);
        let row: Vec<f32> = (0..gl.c)
            .map(|c| (gl.channel(c).iter().map(|&v| v as f64).sum::<f64>() / n as f64) as f32)
            .collect();
        let th = self.conv_v_left.forward(x);
        let mut t = vec![0.0f32; n];
        for (c, &rc) in row.iter().enumerate() {
            t.iter_mut()
                .zip(th.channel(c))
                .for_each(|(a, v)| *a += rc * v);
        }
        softmax_in_place(&mut t);
        t.iter_mut().for_each(|v| *v = sigmoid(*v));

        let mut out = FeatureMap::for_overwrite(x.c, x.h, x.w);
        for c in 0..x.c {
            let g = sigmoid(gate.data[c]);
            let dst = &mut out.data[c * n..(c + 1) * n];
            for ((o, &v), &s) in dst.iter_mut().zip(x.channel(c)).zip(&t) {
                *o = v * g + v * s;
            }
        }
        out
    }
}

fn dot(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| x as f64 * y as f64)
        .sum::<f64>() as f32
}
