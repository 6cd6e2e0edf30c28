//! A study's records (`cassi eval`): each scene's result file, written as
//! the scene finishes and read back by `--resume`, and the summary.

use serde::{Deserialize, Serialize};

use super::Record;
use crate::digests::InputDigests;
use crate::machine::Machine;
use crate::protocol::{SceneResult, Study};
use crate::summary::Summary;
use crate::sweep_rows::Sweeps;

/// A scene's result file: the study it belongs to, the digests of its
/// inputs, then the result.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneRecord {
    pub study: Study,
    pub noise_seed: u64,
    /// Absent in records written before digests existed: such a record is
    /// never reused.
    #[serde(default)]
    pub inputs: Option<InputDigests>,
    pub result: SceneResult,
}

impl Record for SceneRecord {
    const FORMAT: &'static str = "cassi-study-scene";
    const VERSION: u64 = 1;
    const KEYS: &'static [&'static str] = &["study", "noise_seed", "result"];
}

/// Where a study's scenes and mask came from, as its report names them.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StudySetup {
    pub scenes: String,
    pub mask: String,
}

/// A study's `summary.json`: the study, its setup, the machine, the
/// summary over scenes, the sweeps and what the metrics mean.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SummaryRecord {
    pub study: Study,
    pub setup: StudySetup,
    pub machine: Machine,
    pub summary: Summary,
    pub sweeps: Sweeps,
    pub metric_definitions: String,
}

impl Record for SummaryRecord {
    const FORMAT: &'static str = "cassi-study-summary";
    const VERSION: u64 = 1;
    const KEYS: &'static [&'static str] = &["study", "summary", "sweeps"];
}
