//! One sample's feature map, (channels, rows, cols) row-major: the working
//! array of every layer.

#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMap {
    pub c: usize,
    pub h: usize,
    pub w: usize,
    pub data: Vec<f32>,
}

impl FeatureMap {
    pub fn zeros(c: usize, h: usize, w: usize) -> Self {
        Self {
            c,
            h,
            w,
            data: vec![0.0; c * h * w],
        }
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
    /// `self += other`, element-wise (same shape).
    pub fn add_assign(&mut self, other: &FeatureMap) {
        assert_eq!(self.data.len(), other.data.len(), "feature map sizes");
        self.data
            .iter_mut()
            .zip(&other.data)
            .for_each(|(a, b)| *a += b);
    }
    /// Channels `self` then `other` (same rows and cols).
    pub fn concat_channels(&self, other: &FeatureMap) -> FeatureMap {
        assert_eq!((self.h, self.w), (other.h, other.w), "concat sizes");
        let mut data = Vec::with_capacity(self.data.len() + other.data.len());
        data.extend_from_slice(&self.data);
        data.extend_from_slice(&other.data);
        FeatureMap::from_vec(self.c + other.c, self.h, self.w, data)
    }
}
