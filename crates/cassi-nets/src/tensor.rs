//! A dense, row-major f32 array with a shape: the one array type of the
//! networks (PyTorch layout, NCHW for images).

use crate::error::{NetError, Result, shape_str};

#[derive(Debug, Clone, PartialEq)]
pub struct Tensor {
    shape: Vec<usize>,
    data: Vec<f32>,
}

impl Tensor {
    /// Wraps `data` laid out row-major with `shape`; errors if the length does not fit.
    pub fn new(shape: Vec<usize>, data: Vec<f32>) -> Result<Self> {
        let numel: usize = shape.iter().product();
        if numel != data.len() {
            return Err(NetError::Input {
                what: "tensor data".into(),
                got: format!("{} elements", data.len()),
                expected: format!("{} = {numel} elements", shape_str(&shape)),
            });
        }
        Ok(Self { shape, data })
    }

    pub fn zeros(shape: Vec<usize>) -> Self {
        let numel = shape.iter().product();
        Self {
            shape,
            data: vec![0.0; numel],
        }
    }

    pub fn shape(&self) -> &[usize] {
        &self.shape
    }
    pub fn numel(&self) -> usize {
        self.data.len()
    }
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }
    pub fn into_data(self) -> Vec<f32> {
        self.data
    }

    /// Checks that this is an NCHW batch with `channels` channels (any when
    /// `None`) and returns (batch, channels, rows, cols).
    pub fn nchw(&self, what: &str, channels: Option<usize>) -> Result<[usize; 4]> {
        let ok = self.shape.len() == 4 && channels.is_none_or(|c| self.shape[1] == c);
        if !ok || self.data.is_empty() {
            return Err(NetError::Input {
                what: what.into(),
                got: shape_str(&self.shape),
                expected: match channels {
                    Some(c) => format!("(batch, {c}, rows, cols), none empty"),
                    None => "(batch, channels, rows, cols), none empty".into(),
                },
            });
        }
        Ok([self.shape[0], self.shape[1], self.shape[2], self.shape[3]])
    }

    /// The largest absolute element-wise difference to `other`; infinite
    /// when the shapes differ or a difference is NaN (so a comparison
    /// against a tolerance cannot pass by accident).
    pub fn max_abs_diff(&self, other: &Tensor) -> f32 {
        if self.shape != other.shape {
            return f32::INFINITY;
        }
        self.data
            .iter()
            .zip(&other.data)
            .map(|(a, b)| {
                let d = (a - b).abs();
                if d.is_nan() { f32::INFINITY } else { d }
            })
            .fold(0.0, f32::max)
    }
}
