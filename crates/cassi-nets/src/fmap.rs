//! One sample's feature map, (channels, rows, cols) row-major: the working
//! array of every layer. Large maps take and return their storage through
//! [`crate::buffer_pool`].

use crate::buffer_pool;

/// Elements per parallel task of element-wise operations: big enough that
/// rayon's overhead vanishes, small enough to share work on 2 cores.
pub(crate) const ELEMENTWISE_CHUNK: usize = 1 << 15;

#[derive(Debug, PartialEq)]
pub struct FeatureMap {
    pub c: usize,
    pub h: usize,
    pub w: usize,
    pub data: Vec<f32>,
}

/// Copies into pooled storage (a plain `Vec` clone would add a fresh
/// allocation to the pool at every drop, growing it to its bound).
impl Clone for FeatureMap {
    fn clone(&self) -> Self {
        Self::from_slice(self.c, self.h, self.w, &self.data)
    }
}

impl Drop for FeatureMap {
    fn drop(&mut self) {
        buffer_pool::give(std::mem::take(&mut self.data));
    }
}

impl FeatureMap {
    pub fn zeros(c: usize, h: usize, w: usize) -> Self {
        let mut map = Self::for_overwrite(c, h, w);
        map.data.fill(0.0);
        map
    }
    /// A map whose values are unspecified (recycled storage): only for
    /// outputs that write every element.
    pub fn for_overwrite(c: usize, h: usize, w: usize) -> Self {
        let mut data = buffer_pool::take(c * h * w);
        if cfg!(any(test, debug_assertions)) {
            // An element a layer forgot to write shows up as NaN in the
            // unit tests, which compare every op with its definition.
            data.fill(f32::NAN);
        }
        Self { c, h, w, data }
    }
    /// A copy of `data` (c·h·w floats) in pooled storage.
    pub fn from_slice(c: usize, h: usize, w: usize, data: &[f32]) -> Self {
        let mut map = Self::for_overwrite(c, h, w);
        map.data.copy_from_slice(data);
        map
    }
    /// The storage, kept out of the pool.
    pub fn into_data(mut self) -> Vec<f32> {
        std::mem::take(&mut self.data)
    }
    /// Wraps `data`; the caller guarantees `data.len() == c * h * w`.
    pub fn from_vec(c: usize, h: usize, w: usize, data: Vec<f32>) -> Self {
        assert_eq!(data.len(), c * h * w, "feature map size");
        Self { c, h, w, data }
    }
    /// Pixels per channel.
    pub fn plane(&self) -> usize {
        self.h * self.w
    }
    pub fn channel(&self, c: usize) -> &[f32] {
        &self.data[c * self.plane()..(c + 1) * self.plane()]
    }
    /// `self += other`, element-wise (same shape), in parallel chunks.
    pub fn add_assign(&mut self, other: &FeatureMap) {
        use rayon::prelude::*;
        assert_eq!(self.data.len(), other.data.len(), "feature map sizes");
        (self.data.par_chunks_mut(ELEMENTWISE_CHUNK))
            .zip(other.data.par_chunks(ELEMENTWISE_CHUNK))
            .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b));
    }
    /// `self ⊙ other`, element-wise (same shape), in parallel chunks.
    pub fn product(&self, other: &FeatureMap) -> FeatureMap {
        use rayon::prelude::*;
        assert_eq!(self.data.len(), other.data.len(), "feature map sizes");
        let mut out = FeatureMap::for_overwrite(self.c, self.h, self.w);
        (out.data.par_chunks_mut(ELEMENTWISE_CHUNK))
            .zip(self.data.par_chunks(ELEMENTWISE_CHUNK))
            .zip(other.data.par_chunks(ELEMENTWISE_CHUNK))
            .for_each(|((o, a), b)| {
                for ((o, a), b) in o.iter_mut().zip(a).zip(b) {
                    *o = a * b;
                }
            });
        out
    }
    /// Channels `self` then `other` (same rows and cols).
    pub fn concat_channels(&self, other: &FeatureMap) -> FeatureMap {
        assert_eq!((self.h, self.w), (other.h, other.w), "concat sizes");
        let mut out = FeatureMap::for_overwrite(self.c + other.c, self.h, self.w);
        let (a, b) = out.data.split_at_mut(self.data.len());
        a.copy_from_slice(&self.data);
        b.copy_from_slice(&other.data);
        out
    }
}
