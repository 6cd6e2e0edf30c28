//! Decoding stored numbers straight into what the caller keeps: an f32 array
//! (checked finite and in range, reordered from column-major on the fly) or
//! running statistics. No f64 copy of a variable is ever held, so a load
//! costs its f32 result plus the file, and `describe` costs nothing per
//! element.
//!
//! Readers hand over the stored bytes in pieces (a slice of the file, or
//! chunks of an inflating stream), always cut at element boundaries.

use std::io::Read;
use std::path::Path;

use serde::Serialize;

use crate::array::{Elem, Endian, index_str};
use crate::error::{IoError, Result};

/// Statistics of a numeric variable. `min`, `max` and `mean` are over the
/// finite values (None when there are none).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Stats {
    pub count: usize,
    pub min: Option<f64>,
    pub max: Option<f64>,
    pub mean: Option<f64>,
    /// Number of NaN/±Inf values.
    pub non_finite: usize,
}

/// IEEE half → double, exact (subnormals, ±inf and NaN included).
fn f16_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let frac = (h & 0x3ff) as f64;
    sign * match exp {
        0 => frac * 2f64.powi(-24),
        31 if frac == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        _ => (1.0 + frac / 1024.0) * 2f64.powi(exp - 15),
    }
}

/// Calls `f` on every whole element of `bytes`, in order.
#[inline]
pub(crate) fn for_each_value(bytes: &[u8], el: Elem, mut f: impl FnMut(f64)) {
    macro_rules! each {
        ($n:literal, $conv:expr) => {
            for c in bytes.chunks_exact($n) {
                let mut a = [0u8; $n];
                a.copy_from_slice(c);
                if el.endian == Endian::Big {
                    a.reverse();
                }
                #[allow(clippy::redundant_closure_call)]
                f($conv(a));
            }
        };
    }
    match (el.kind, el.size) {
        ('f', 2) => each!(2, |a| f16_to_f64(u16::from_le_bytes(a))),
        ('f', 4) => each!(4, |a| f32::from_le_bytes(a) as f64),
        ('f', 8) => each!(8, f64::from_le_bytes),
        ('i', 1) => bytes.iter().for_each(|&b| f(b as i8 as f64)),
        ('u', 1) => bytes.iter().for_each(|&b| f(b as f64)),
        ('b', 1) => bytes.iter().for_each(|&b| f((b != 0) as u8 as f64)),
        ('i', 2) => each!(2, |a| i16::from_le_bytes(a) as f64),
        ('u', 2) => each!(2, |a| u16::from_le_bytes(a) as f64),
        ('i', 4) => each!(4, |a| i32::from_le_bytes(a) as f64),
        ('u', 4) => each!(4, |a| u32::from_le_bytes(a) as f64),
        ('i', 8) => each!(8, |a| i64::from_le_bytes(a) as f64),
        ('u', 8) => each!(8, |a| u64::from_le_bytes(a) as f64),
        _ => {}
    }
}

/// Where decoded values go.
pub(crate) trait Sink {
    /// Takes whole elements of the stored bytes, in storage order.
    fn take(&mut self, bytes: &[u8]);
}

/// The 0-based multi-index of column-major offset `i` in `shape`, as `[a, b, c]`.
pub(crate) fn index_str_f(shape: &[usize], mut i: usize) -> String {
    let mut idx = vec![0usize; shape.len()];
    for (d, &n) in shape.iter().enumerate() {
        if n > 0 {
            idx[d] = i % n;
            i /= n;
        }
    }
    format!(
        "[{}]",
        idx.iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// Decodes into a C-order f32 array of `shape`, checking every value is
/// finite and fits f32. Storage in column-major order (`fortran`) is
/// scattered to its C-order place as it arrives, so no second copy is made.
pub(crate) struct F32Sink {
    el: Elem,
    shape: Vec<usize>,
    fortran: bool,
    out: Vec<f32>,
    /// Elements received.
    pos: usize,
    /// Column-major odometer: multi-index of the next element and its C offset.
    idx: Vec<usize>,
    cstride: Vec<usize>,
    dst: usize,
    /// First bad value: storage position, value, whether it is merely out of range.
    bad: Option<(usize, f64, bool)>,
}

impl F32Sink {
    /// `count` must be the element count of `shape`, already checked against
    /// the budget by the caller.
    pub(crate) fn new(el: Elem, shape: &[usize], count: usize, fortran: bool) -> Self {
        let mut cstride = vec![1usize; shape.len()];
        for d in (0..shape.len().saturating_sub(1)).rev() {
            cstride[d] = cstride[d + 1].saturating_mul(shape[d + 1]);
        }
        F32Sink {
            el,
            shape: shape.to_vec(),
            fortran: fortran && shape.len() >= 2,
            out: vec![0f32; count],
            pos: 0,
            idx: vec![0; shape.len()],
            cstride,
            dst: 0,
            bad: None,
        }
    }

    /// The array, or the error for its first non-finite / out-of-range value,
    /// or a truncation error if fewer values arrived than the shape needs.
    pub(crate) fn finish(self, path: &Path, name: &str) -> Result<Vec<f32>> {
        if let Some((p, value, range)) = self.bad {
            let index = if self.fortran {
                index_str_f(&self.shape, p)
            } else {
                index_str(&self.shape, p)
            };
            let (path, name) = (path.to_path_buf(), name.to_string());
            return Err(if range {
                IoError::OutOfRange {
                    path,
                    name,
                    value,
                    index,
                }
            } else {
                IoError::NonFinite {
                    path,
                    name,
                    value,
                    index,
                }
            });
        }
        if self.pos != self.out.len() {
            return Err(IoError::Truncated {
                path: path.to_path_buf(),
                format: "data file",
                detail: format!(
                    "variable '{}' holds {} of the {} values its shape needs",
                    crate::escape::esc(name),
                    self.pos,
                    self.out.len()
                ),
            });
        }
        Ok(self.out)
    }
}

impl Sink for F32Sink {
    fn take(&mut self, bytes: &[u8]) {
        let n = self.out.len();
        let fortran = self.fortran;
        let (out, idx, cstride, shape) = (&mut self.out, &mut self.idx, &self.cstride, &self.shape);
        let (mut pos, mut dst, mut bad) = (self.pos, self.dst, self.bad);
        for_each_value(bytes, self.el, |v| {
            if pos >= n {
                pos += 1;
                return;
            }
            let f = v as f32;
            if !f.is_finite() && bad.is_none() {
                bad = Some((pos, v, v.is_finite()));
            }
            if fortran {
                out[dst] = f;
                // Advance the column-major odometer (first axis fastest).
                let mut d = 0;
                while d < shape.len() {
                    idx[d] += 1;
                    dst += cstride[d];
                    if idx[d] < shape[d] {
                        break;
                    }
                    dst -= shape[d] * cstride[d];
                    idx[d] = 0;
                    d += 1;
                }
            } else {
                out[pos] = f;
            }
            pos += 1;
        });
        self.pos = pos;
        self.dst = dst;
        self.bad = bad;
    }
}

/// Running min / max / mean / non-finite count, in any order.
pub(crate) struct StatsSink {
    el: Elem,
    count: usize,
    finite: usize,
    min: f64,
    max: f64,
    sum: f64,
}

impl StatsSink {
    pub(crate) fn new(el: Elem) -> Self {
        StatsSink {
            el,
            count: 0,
            finite: 0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            sum: 0.0,
        }
    }
    pub(crate) fn finish(self) -> Stats {
        let some = |x: f64| (self.finite > 0).then_some(x);
        Stats {
            count: self.count,
            min: some(self.min),
            max: some(self.max),
            mean: some(self.sum / self.finite.max(1) as f64),
            non_finite: self.count - self.finite,
        }
    }
}

impl Sink for StatsSink {
    fn take(&mut self, bytes: &[u8]) {
        let (mut count, mut finite, mut min, mut max, mut sum) =
            (self.count, self.finite, self.min, self.max, self.sum);
        for_each_value(bytes, self.el, |v| {
            count += 1;
            if v.is_finite() {
                finite += 1;
                min = min.min(v);
                max = max.max(v);
                sum += v;
            }
        });
        (self.count, self.finite, self.min, self.max, self.sum) = (count, finite, min, max, sum);
    }
}

/// The most bytes `compressed` bytes of a deflate (zlib) stream can inflate
/// to: deflate cannot do better than about 1032:1, so anything more is a lie
/// that need not be inflated to be caught.
pub(crate) fn inflate_bound(compressed: u64) -> u64 {
    compressed.saturating_mul(1040).saturating_add(1024)
}

/// Bytes per piece handed to a sink from a stream (a multiple of every element size).
const PIECE: usize = 1 << 16;

/// Feeds at most `nbytes` from `r` to `sink` in element-aligned pieces, never
/// reading past `nbytes` (the hard cap of an inflating stream). Returns how
/// many bytes were delivered: fewer than `nbytes` when the stream ended early.
pub(crate) fn pump(
    r: &mut dyn Read,
    nbytes: u64,
    el_size: usize,
    sink: &mut dyn Sink,
) -> std::io::Result<u64> {
    let mut buf = vec![0u8; PIECE.min(usize::try_from(nbytes).unwrap_or(PIECE)).max(8)];
    let mut done = 0u64;
    let mut held = 0usize; // bytes in buf not yet handed over (a partial element)
    while done < nbytes {
        let want = (nbytes - done).min((buf.len() - held) as u64) as usize;
        let got = match r.read(&mut buf[held..held + want]) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        done += got as u64;
        let have = held + got;
        let whole = have - have % el_size.max(1);
        sink.take(&buf[..whole]);
        buf.copy_within(whole..have, 0);
        held = have - whole;
    }
    Ok(done - held as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fortran_scatter_matches_the_index_formula() {
        // MATLAB A(r, c, b) = 100 r + 10 c + b for size (2, 3, 4), stored column-major as u16.
        let shape = [2usize, 3, 4];
        let mut bytes = Vec::new();
        for b in 0..4u16 {
            for c in 0..3u16 {
                for r in 0..2u16 {
                    bytes.extend((100 * r + 10 * c + b).to_le_bytes());
                }
            }
        }
        let el = Elem::new('u', 2, Endian::Little).unwrap();
        let mut s = F32Sink::new(el, &shape, 24, true);
        // Hand it over in odd pieces, as a stream would.
        s.take(&bytes[..6]);
        s.take(&bytes[6..]);
        let v = s.finish(Path::new("x"), "a").unwrap();
        let mut i = 0;
        for r in 0..2 {
            for c in 0..3 {
                for b in 0..4 {
                    assert_eq!(v[i], (100 * r + 10 * c + b) as f32);
                    i += 1;
                }
            }
        }
    }

    #[test]
    fn half_floats_and_bad_values() {
        assert_eq!(f16_to_f64(0x3c00), 1.0);
        assert_eq!(f16_to_f64(0xc000), -2.0);
        assert_eq!(f16_to_f64(0x7bff), 65504.0);
        let el = Elem::new('f', 8, Endian::Little).unwrap();
        let mut s = F32Sink::new(el, &[2, 2], 4, true);
        let vals = [0.0f64, 1.0, 1e300, 2.0];
        s.take(
            &vals
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect::<Vec<_>>(),
        );
        let e = s.finish(Path::new("x"), "a").unwrap_err().to_string();
        assert!(
            e.contains("outside the range of f32") && e.contains("[0, 1]"),
            "{e}"
        );
    }
}
