//! Dense f32 arrays with the project's fixed layouts: [`Cube`] is
//! (bands, rows, cols) and [`Frame`] is (rows, cols), both row-major.

use crate::error::{CassiError, Result, shape_error};

/// A hyperspectral cube, layout (bands, rows, cols) = (L, H, W), row-major.
/// Band 0 is the shortest wavelength.
#[derive(Debug, Clone, PartialEq)]
pub struct Cube {
    bands: usize,
    rows: usize,
    cols: usize,
    data: Vec<f32>,
}

impl Cube {
    pub fn zeros(bands: usize, rows: usize, cols: usize) -> Self {
        Self {
            bands,
            rows,
            cols,
            data: vec![0.0; bands * rows * cols],
        }
    }

    /// Wraps `data` laid out as (bands, rows, cols); errors if the length does not fit.
    pub fn from_vec(bands: usize, rows: usize, cols: usize, data: Vec<f32>) -> Result<Self> {
        if data.len() != bands * rows * cols {
            return Err(shape_error(
                "cube data",
                format!("{} elements", data.len()),
                format!("{bands}×{rows}×{cols} = {} elements", bands * rows * cols),
            ));
        }
        Ok(Self {
            bands,
            rows,
            cols,
            data,
        })
    }

    pub fn bands(&self) -> usize {
        self.bands
    }
    pub fn rows(&self) -> usize {
        self.rows
    }
    pub fn cols(&self) -> usize {
        self.cols
    }
    /// (bands, rows, cols).
    pub fn shape(&self) -> (usize, usize, usize) {
        (self.bands, self.rows, self.cols)
    }
    pub fn band_len(&self) -> usize {
        self.rows * self.cols
    }
    pub fn as_slice(&self) -> &[f32] {
        &self.data
    }
    pub fn as_mut_slice(&mut self) -> &mut [f32] {
        &mut self.data
    }
    pub fn into_vec(self) -> Vec<f32> {
        self.data
    }
    /// The smallest and largest value ((+∞, −∞) when empty).
    pub fn min_max(&self) -> (f32, f32) {
        min_max(&self.data)
    }
    pub fn band(&self, k: usize) -> &[f32] {
        let n = self.band_len();
        &self.data[k * n..(k + 1) * n]
    }
    pub fn band_mut(&mut self, k: usize) -> &mut [f32] {
        let n = self.band_len();
        &mut self.data[k * n..(k + 1) * n]
    }
    pub fn get(&self, band: usize, row: usize, col: usize) -> f32 {
        self.data[(band * self.rows + row) * self.cols + col]
    }
    pub fn set(&mut self, band: usize, row: usize, col: usize, value: f32) {
        self.data[(band * self.rows + row) * self.cols + col] = value;
    }

    /// A copy clipped to [0, 1]: what reconstructions are scored as (the
    /// metrics' convention; scenes live in [0, 1]).
    pub fn clipped_to_unit(&self) -> Cube {
        let mut c = self.clone();
        c.data.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        c
    }

    /// Errors naming `what` and the first (band, row, col) that is NaN or ±Inf.
    pub fn check_finite(&self, what: &str) -> Result<()> {
        match self.data.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => {
                let n = self.band_len();
                Err(CassiError::NonFinite {
                    what: what.to_string(),
                    value: self.data[i],
                    location: format!(
                        "(band {}, row {}, col {})",
                        i / n,
                        (i % n) / self.cols,
                        i % self.cols
                    ),
                })
            }
        }
    }
}

/// A 2-D f32 raster (rows, cols), row-major: a mask, a measurement, a band.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    rows: usize,
    cols: usize,
    data: Vec<f32>,
}

/// A coded aperture: transmission per pixel in [0, 1].
pub type Mask = Frame;
/// A detector snapshot (rows, detector cols), values ≥ 0.
pub type Measurement = Frame;

impl Frame {
    pub fn zeros(rows: usize, cols: usize) -> Self {
        Self {
            rows,
            cols,
            data: vec![0.0; rows * cols],
        }
    }

    /// Wraps `data` laid out as (rows, cols); errors if the length does not fit.
    pub fn from_vec(rows: usize, cols: usize, data: Vec<f32>) -> Result<Self> {
        if data.len() != rows * cols {
            return Err(shape_error(
                "frame data",
                format!("{} elements", data.len()),
                format!("{rows}×{cols} = {} elements", rows * cols),
            ));
        }
        Ok(Self { rows, cols, data })
    }

    pub fn rows(&self) -> usize {
        self.rows
    }
    pub fn cols(&self) -> usize {
        self.cols
    }
    /// (rows, cols).
    pub fn shape(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }
    pub fn as_slice(&self) -> &[f32] {
        &self.data
    }
    pub fn as_mut_slice(&mut self) -> &mut [f32] {
        &mut self.data
    }
    pub fn into_vec(self) -> Vec<f32> {
        self.data
    }
    pub fn row(&self, r: usize) -> &[f32] {
        &self.data[r * self.cols..(r + 1) * self.cols]
    }
    pub fn row_mut(&mut self, r: usize) -> &mut [f32] {
        &mut self.data[r * self.cols..(r + 1) * self.cols]
    }
    /// Rows `first..end` as a frame of their own; errors naming the range
    /// when it is empty or runs past the last row.
    pub fn rows_range(&self, first: usize, end: usize) -> Result<Frame> {
        if first >= end || end > self.rows {
            return Err(shape_error(
                "row range",
                format!("{first}..{end}"),
                format!("a non-empty range within 0..{}", self.rows),
            ));
        }
        let data = self.data[first * self.cols..end * self.cols].to_vec();
        Ok(Frame {
            rows: end - first,
            cols: self.cols,
            data,
        })
    }
    pub fn get(&self, row: usize, col: usize) -> f32 {
        self.data[row * self.cols + col]
    }
    pub fn set(&mut self, row: usize, col: usize, value: f32) {
        self.data[row * self.cols + col] = value;
    }
    pub fn max(&self) -> f32 {
        self.data.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }
    /// (min, max) of the values; (+∞, −∞) for an empty frame.
    pub fn min_max(&self) -> (f32, f32) {
        min_max(&self.data)
    }

    /// Errors naming `what` and the first (row, col) that is NaN or ±Inf.
    pub fn check_finite(&self, what: &str) -> Result<()> {
        match self.data.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => Err(CassiError::NonFinite {
                what: what.to_string(),
                value: self.data[i],
                location: format!("(row {}, col {})", i / self.cols, i % self.cols),
            }),
        }
    }
}

fn min_max(data: &[f32]) -> (f32, f32) {
    data.iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_layout_is_bands_rows_cols_row_major() {
        let c = Cube::from_vec(2, 2, 3, (0..12).map(|v| v as f32).collect()).unwrap();
        // element (band 1, row 0, col 2) sits at 1*6 + 0*3 + 2 = 8
        assert_eq!(c.get(1, 0, 2), 8.0);
        assert_eq!(c.band(1), &[6.0, 7.0, 8.0, 9.0, 10.0, 11.0]);
    }

    #[test]
    fn a_row_range_is_those_rows_and_a_bad_one_is_named() {
        let f = Frame::from_vec(4, 3, (0..12).map(|v| v as f32).collect()).unwrap();
        let band = f.rows_range(1, 3).unwrap();
        assert_eq!(band.shape(), (2, 3));
        assert_eq!(band.as_slice(), &[3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
        for (first, end) in [(2, 2), (3, 1), (1, 5)] {
            let e = f.rows_range(first, end).unwrap_err().to_string();
            assert!(
                e.contains(&format!("{first}..{end}")) && e.contains("0..4"),
                "{e}"
            );
        }
    }

    #[test]
    fn wrong_length_and_non_finite_are_errors() {
        assert!(Cube::from_vec(2, 2, 2, vec![0.0; 7]).is_err());
        let mut f = Frame::zeros(3, 4);
        f.set(2, 1, f32::NAN);
        let e = f.check_finite("mask").unwrap_err().to_string();
        assert!(e.contains("mask") && e.contains("row 2, col 1"), "{e}");
    }
}
