//! The sweeps' results as data: sensitivity points, ablation rows and the
//! `Sweeps` a study's summary carries. Kept apart from the runner in
//! `sweep` so records and reports can name them without depending on it.

use cassi_core::Mismatch;
use serde::{Deserialize, Serialize};

use crate::summary::Summary;

/// One point of a sensitivity curve.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SensitivityPoint {
    pub scale: f64,
    pub mismatch: Mismatch,
    pub summary: Summary,
}

/// Which model an ablation row reconstructs with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AblationVariant {
    /// The nominal model (Scenario II).
    Nominal,
    /// The parameters after the preset's search stages without refinement:
    /// `paper`: the grids (stages 0–1); `default`: the correlation start.
    SearchOnly,
    /// The whole preset (Scenario III).
    Full,
    /// The true model (Scenario IV).
    Oracle,
}

impl AblationVariant {
    pub const ALL: [AblationVariant; 4] =
        [Self::Nominal, Self::SearchOnly, Self::Full, Self::Oracle];

    pub fn label(self, preset: &str) -> &'static str {
        match (self, preset) {
            (Self::Nominal, _) => "nominal (II)",
            (Self::SearchOnly, "paper") => "grid only (stages 0–1)",
            (Self::SearchOnly, _) => "first stage only",
            (Self::Full, _) => "full pipeline (III)",
            (Self::Oracle, _) => "oracle (IV)",
        }
    }
}

/// Mean PSNR of one method with one preset and variant.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AblationRow {
    pub preset: String,
    pub method: String,
    pub variant: AblationVariant,
    pub label: String,
    pub psnr: f64,
    /// Root-mean-square error over dx, dy (px) and θ (°) of this variant's
    /// parameters, over scenes.
    pub pose_rmse_px: f64,
    pub calibration_seconds_mean: f64,
}

/// The optional sweeps of a study.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Sweeps {
    /// Sensitivity curves, one per preset.
    pub sensitivity: Vec<(String, Vec<SensitivityPoint>)>,
    pub ablation: Option<Vec<AblationRow>>,
}
