//! Resizing images for display: area averaging when shrinking, nearest
//! pixel when enlarging (so that enlarged pixels stay crisp blocks).

/// Resizes an interleaved RGB image `(rows, cols)` to `(h, w)`.
pub(crate) fn resize_rgb(src: &[u8], rows: usize, cols: usize, h: usize, w: usize) -> Vec<u8> {
    let mut out = vec![0u8; 3 * h * w];
    let sy = rows as f64 / h as f64;
    let sx = cols as f64 / w as f64;
    // Source index ranges per destination row / column.
    let span = |d: usize, s: f64, n: usize| -> (usize, usize) {
        if s <= 1.0 {
            let i = (((d as f64 + 0.5) * s) as usize).min(n - 1);
            (i, i + 1)
        } else {
            let a = ((d as f64 * s).floor() as usize).min(n - 1);
            let b = (((d + 1) as f64 * s).ceil() as usize).clamp(a + 1, n);
            (a, b)
        }
    };
    let xs: Vec<(usize, usize)> = (0..w).map(|x| span(x, sx, cols)).collect();
    for y in 0..h {
        let (r0, r1) = span(y, sy, rows);
        for (x, &(c0, c1)) in xs.iter().enumerate() {
            let mut acc = [0u32; 3];
            for r in r0..r1 {
                for c in c0..c1 {
                    let i = 3 * (r * cols + c);
                    for k in 0..3 {
                        acc[k] += u32::from(src[i + k]);
                    }
                }
            }
            let n = ((r1 - r0) * (c1 - c0)) as u32;
            let o = 3 * (y * w + x);
            for k in 0..3 {
                out[o + k] = ((acc[k] + n / 2) / n) as u8;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enlarge_repeats_and_shrink_averages() {
        // 1×2: black, white.
        let src = [0, 0, 0, 255, 255, 255];
        let big = resize_rgb(&src, 1, 2, 2, 4);
        assert_eq!(&big[0..3], &[0, 0, 0]);
        assert_eq!(&big[3..6], &[0, 0, 0]);
        assert_eq!(&big[6..9], &[255, 255, 255]);
        let small = resize_rgb(&src, 1, 2, 1, 1);
        assert_eq!(small, vec![128, 128, 128]);
    }
}
