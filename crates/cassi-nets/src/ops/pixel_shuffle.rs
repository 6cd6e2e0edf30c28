//! Pixel (un)shuffle by 2, as torch.nn.PixelUnshuffle(2) / PixelShuffle(2),
//! and bottom/right replicate padding to even sizes (HSI-SDeCNN).

use crate::fmap::FeatureMap;

/// u[4c + 2a + e, i, j] = x[c, 2i + a, 2j + e]; rows and cols must be even.
pub(crate) fn pixel_unshuffle2(x: &FeatureMap) -> FeatureMap {
    assert!(
        x.h.is_multiple_of(2) && x.w.is_multiple_of(2),
        "pixel unshuffle needs even sizes"
    );
    let (h2, w2) = (x.h / 2, x.w / 2);
    let mut out = FeatureMap::for_overwrite(4 * x.c, h2, w2);
    for c in 0..x.c {
        for a in 0..2 {
            for e in 0..2 {
                let dst = &mut out.data[(4 * c + 2 * a + e) * h2 * w2..][..h2 * w2];
                for i in 0..h2 {
                    for j in 0..w2 {
                        dst[i * w2 + j] = x.data[(c * x.h + 2 * i + a) * x.w + 2 * j + e];
                    }
                }
            }
        }
    }
    out
}

/// out[c, 2i + a, 2j + e] = t[4c + 2a + e, i, j]; the inverse of [`pixel_unshuffle2`].
pub(crate) fn pixel_shuffle2(t: &FeatureMap) -> FeatureMap {
    assert!(
        t.c.is_multiple_of(4),
        "pixel shuffle needs a multiple of 4 channels"
    );
    let (h, w) = (2 * t.h, 2 * t.w);
    let mut out = FeatureMap::for_overwrite(t.c / 4, h, w);
    for c in 0..t.c / 4 {
        for a in 0..2 {
            for e in 0..2 {
                let src = t.channel(4 * c + 2 * a + e);
                for i in 0..t.h {
                    for j in 0..t.w {
                        out.data[(c * h + 2 * i + a) * w + 2 * j + e] = src[i * t.w + j];
                    }
                }
            }
        }
    }
    out
}

/// Pads the bottom and right by one replicated pixel where rows / cols are odd.
pub(crate) fn replicate_pad_to_even(x: &FeatureMap) -> FeatureMap {
    let (h, w) = (x.h + x.h % 2, x.w + x.w % 2);
    if (h, w) == (x.h, x.w) {
        return x.clone();
    }
    let mut out = FeatureMap::for_overwrite(x.c, h, w);
    for c in 0..x.c {
        for y in 0..h {
            let src = &x.data[(c * x.h + y.min(x.h - 1)) * x.w..][..x.w];
            let dst = &mut out.data[(c * h + y) * w..][..w];
            dst[..x.w].copy_from_slice(src);
            if w > x.w {
                dst[x.w] = src[x.w - 1];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unshuffle_places_pixels_as_torch_and_shuffle_inverts_it() {
        // One channel, 2×4: u[2a+e, 0, j] = x[a, 2j+e].
        let x = FeatureMap::from_vec(1, 2, 4, (0..8).map(|v| v as f32).collect());
        let u = pixel_unshuffle2(&x);
        assert_eq!((u.c, u.h, u.w), (4, 1, 2));
        assert_eq!(u.data, vec![0.0, 2.0, 1.0, 3.0, 4.0, 6.0, 5.0, 7.0]);
        assert_eq!(pixel_shuffle2(&u), x);
    }

    #[test]
    fn replicate_padding_copies_the_last_row_and_column() {
        let x = FeatureMap::from_vec(1, 1, 3, vec![1.0, 2.0, 3.0]);
        let p = replicate_pad_to_even(&x);
        assert_eq!((p.h, p.w), (2, 4));
        assert_eq!(p.data, vec![1.0, 2.0, 3.0, 3.0, 1.0, 2.0, 3.0, 3.0]);
    }
}
