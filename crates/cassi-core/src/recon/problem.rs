//! What every model-based recipe starts from and ends with: the assumed
//! instrument's operator with the measurement fitted to its detector, and
//! the reconstruction a solver's solution becomes.

use crate::cube::{Cube, Frame, Measurement};
use crate::error::Result;
use crate::optics::ModelOperator;
use crate::solvers::Solution;

use super::model::Model;

/// A reconstruction and the facts a report needs.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    pub cube: Cube,
    pub solution_iterations: usize,
    pub stop: crate::solvers::StopReason,
    pub relative_residual: f64,
    /// Detector columns of the measurement and of the model, when they
    /// differed and the measurement was cropped or zero-padded on the right.
    pub width_fitted: Option<(usize, usize)>,
}

/// Crops or zero-pads `measurement` on the right to `cols` columns: the
/// model's detector width (a drifted a1 changes it by a column or two).
pub fn fit_width(measurement: &Measurement, cols: usize) -> Frame {
    let rows = measurement.rows();
    let keep = cols.min(measurement.cols());
    let mut out = Frame::zeros(rows, cols);
    for r in 0..rows {
        out.row_mut(r)[..keep].copy_from_slice(&measurement.row(r)[..keep]);
    }
    out
}

/// What every model-based recipe starts from: the operator of the assumed
/// instrument and the measurement fitted to its detector width. Recipes
/// outside this module (e.g. plug-and-play with a learned denoiser in
/// cassi-nets) build one, run a solver on it and call
/// [`finish`](Self::finish), so the checks and width handling are shared.
pub struct ModelProblem {
    /// The model's operator (blurred when the parameters carry a blur).
    pub op: ModelOperator,
    /// The measurement, cropped or zero-padded on the right to the model's
    /// detector width.
    pub y: Frame,
    /// (measurement columns, model columns) when they differed.
    pub width_fitted: Option<(usize, usize)>,
}

impl ModelProblem {
    /// The instrument `model` assumes, with `measurement` fitted to its
    /// detector.
    pub fn new(measurement: &Measurement, model: &Model) -> Result<Self> {
        let nominal_mask = model.nominal_mask();
        measurement.check_finite("measurement")?;
        if measurement.rows() != nominal_mask.rows() {
            return Err(crate::error::shape_error(
                "measurement rows",
                format!("{}", measurement.rows()),
                format!("{} (the mask's rows)", nominal_mask.rows()),
            ));
        }
        let op = model.operator()?;
        let (_, det_cols) = op.measurement_shape();
        let width_fitted =
            (measurement.cols() != det_cols).then_some((measurement.cols(), det_cols));
        let y = if width_fitted.is_some() {
            fit_width(measurement, det_cols)
        } else {
            measurement.clone()
        };
        Ok(Self {
            op,
            y,
            width_fitted,
        })
    }

    /// (bands, rows, cols) of the cube to reconstruct.
    pub fn cube_shape(&self) -> (usize, usize, usize) {
        self.op.cube_shape()
    }

    /// A solver's solution as this problem's reconstruction.
    pub fn finish(&self, solution: Solution) -> Reconstruction {
        Reconstruction {
            cube: solution.cube,
            solution_iterations: solution.iterations,
            stop: solution.stop,
            relative_residual: solution.relative_residual,
            width_fitted: self.width_fitted,
        }
    }
}
