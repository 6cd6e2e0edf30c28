//! Max-pooling, 3×3 window, stride 1, padding 1 (the padding never wins,
//! as PyTorch's −∞ padding).

use rayon::prelude::*;

use crate::fmap::FeatureMap;

pub(crate) fn max_pool_3x3(x: &FeatureMap) -> FeatureMap {
    let (h, w) = (x.h, x.w);
    let mut out = FeatureMap::for_overwrite(x.c, h, w);
    out.data
        .par_chunks_mut(h * w)
        .enumerate()
        .for_each(|(c, dst)| {
            let src = x.channel(c);
            for y in 0..h {
                let (y0, y1) = (y.saturating_sub(1), (y + 2).min(h));
                for q in 0..w {
                    let (q0, q1) = (q.saturating_sub(1), (q + 2).min(w));
                    let mut m = f32::NEG_INFINITY;
                    for yy in y0..y1 {
                        for v in &src[yy * w + q0..yy * w + q1] {
                            m = m.max(*v);
                        }
                    }
                    dst[y * w + q] = m;
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn takes_the_max_of_the_window_clipped_at_edges() {
        let x = FeatureMap::from_vec(1, 2, 3, vec![1.0, -5.0, 2.0, -1.0, -2.0, -3.0]);
        let y = max_pool_3x3(&x);
        assert_eq!(y.data, vec![1.0, 2.0, 2.0, 1.0, 2.0, 2.0]);
        let neg = FeatureMap::from_vec(1, 1, 2, vec![-7.0, -9.0]);
        assert_eq!(max_pool_3x3(&neg).data, vec![-7.0, -7.0]);
    }
}
