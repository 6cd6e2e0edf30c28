//! The sweeps' results as data: sensitivity points, ablation rows and the
//! `Sweeps` a study's summary carries. Kept apart from the runner in
//! `sweep` so records and reports can name them without depending on it.

use cassi_core::Mismatch;
use cassi_core::calib::Preset;
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

    /// The row's label for `preset` (the search-only variant is named by
    /// the preset's search).
    pub fn label(self, preset: &Preset) -> &'static str {
        match self {
            Self::SearchOnly => preset.search_label(),
            v => v.generic_label(),
        }
    }

    /// The label every preset shares.
    pub fn generic_label(self) -> &'static str {
        match self {
            Self::Nominal => "nominal (II)",
            Self::SearchOnly => "search stages only",
            Self::Full => "full pipeline (III)",
            Self::Oracle => "oracle (IV)",
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
