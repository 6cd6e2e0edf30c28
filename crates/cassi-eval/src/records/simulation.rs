//! The simulation sidecar: the JSON record written beside every simulated
//! measurement (`cassi simulate`), everything needed to reproduce it.

use std::path::{Path, PathBuf};

use cassi_core::Instrument;
use cassi_core::optics::{PhysicalSpec, SimulationSpec};
use serde::{Deserialize, Serialize};

use super::Record;

/// Where the sidecar of a measurement goes: `out/meas.npy` → `out/meas.json`.
pub fn sidecar_path(measurement: &Path) -> PathBuf {
    measurement.with_extension("json")
}

/// Where an input array came from.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Source {
    File {
        path: PathBuf,
        variable: Option<String>,
        /// The array's shape as used: (bands, rows, cols) or (rows, cols).
        shape: Vec<usize>,
    },
    /// The embedded procedural scene.
    Synthetic {
        seed: u64,
        rows: usize,
        cols: usize,
        bands: usize,
    },
    /// An i.i.d. binary mask.
    Random {
        seed: u64,
        open_fraction: f64,
        rows: usize,
        cols: usize,
    },
}

/// The measurement file a sidecar describes.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MeasurementInfo {
    pub path: PathBuf,
    /// (rows, detector cols).
    pub shape: [usize; 2],
    pub min: f32,
    pub max: f32,
}

/// What made a simulated measurement.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SimulationRecord {
    pub cassi_version: String,
    pub scene: Source,
    pub mask: Source,
    /// The nominal instrument (what a reconstructor assumes).
    pub instrument: Instrument,
    /// The true instrument and the noise.
    pub simulation: SimulationSpec,
    /// Present when the measurement came from the physical (oversampled)
    /// instrument (`cassi simulate --oversample`): its grid, blur, detector
    /// and ADC. `simulation.model` then only names the S = 1 limit
    /// (subpixel). Absent in sidecars from the discrete models.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub physical: Option<PhysicalSpec>,
    pub measurement: MeasurementInfo,
}

impl Record for SimulationRecord {
    const FORMAT: &'static str = "cassi-simulation";
    const VERSION: u64 = 1;
    const KEYS: &'static [&'static str] = &["simulation", "measurement"];
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sidecar written before the physical instrument existed still parses
    /// (no `physical`), and a physical one round-trips.
    #[test]
    fn old_sidecars_parse_and_physical_ones_round_trip() {
        let old = r#"{
          "cassi_version": "0.1.0",
          "scene": {"kind": "synthetic", "seed": 0, "rows": 8, "cols": 8, "bands": 2},
          "mask": {"kind": "random", "seed": 1, "open_fraction": 0.5, "rows": 8, "cols": 8},
          "instrument": {"bands": 2, "stride": 2.0, "wavelengths_nm": [450.0, 650.0]},
          "simulation": {
            "mismatch": {"dx": 0.0, "dy": 0.0, "theta_deg": 0.0, "a1": 2.0, "alpha_deg": 0.0},
            "model": "rounded",
            "noise": {"photon_peak": 100000.0, "read_noise": 0.01, "seed": 0}
          },
          "measurement": {"path": "m.npy", "shape": [8, 10], "min": 0.0, "max": 1.0}
        }"#;
        let mut record: SimulationRecord = serde_json::from_str(old).unwrap();
        assert!(record.physical.is_none());
        assert!(!serde_json::to_string(&record).unwrap().contains("physical"));
        record.physical = Some(PhysicalSpec {
            oversample: 4,
            blur_sigma_px: 0.5,
            detector: Some((8, 11)),
            ..Default::default()
        });
        let back: SimulationRecord =
            serde_json::from_str(&serde_json::to_string(&record).unwrap()).unwrap();
        assert_eq!(back.physical, record.physical);
    }
}
