//! The machine a run was measured on, for benchmark and study records.

use serde::{Deserialize, Serialize};

/// The machine a study ran on, for the record.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Machine {
    pub cpu: String,
    pub threads: usize,
    pub os: String,
    /// Which compiled copy of cassi-core's kernels ran (`portable`, `avx`,
    /// `avx512`; [`cassi_core::kernel_copy`]): the same answers, not the
    /// same times. Absent in records made before the field (stop 64): up
    /// to d42cc36 they ran `avx` on x86-64 CPUs with AVX.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub kernels: String,
}

impl Machine {
    pub fn this() -> Self {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split(':').nth(1))
                    .map(|m| m.trim().to_string())
            })
            .unwrap_or_else(|| "unknown CPU".into());
        Self {
            cpu,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            os: std::env::consts::OS.to_string(),
            kernels: cassi_core::kernel_copy().to_string(),
        }
    }
}
