//! What the cassi-core bench binaries share: the timing rule, the machine
//! they ran on, and where their JSON goes.
#![allow(dead_code)] // each bench uses its own subset

use std::time::Instant;

/// Median of `runs` timings of `f` in milliseconds, after one warm-up call.
pub fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// The CPU's model name (`unknown` where /proc/cpuinfo does not say).
pub fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

/// Where `bench/results/<name>` (or $CASSI_BENCH_OUT) goes, checked
/// before the work: its folder must exist, so a bad path fails at once
/// instead of after minutes of timing.
pub fn record_path(name: &str) -> std::path::PathBuf {
    let path =
        std::path::PathBuf::from(std::env::var("CASSI_BENCH_OUT").unwrap_or_else(|_| {
            format!("{}/../../bench/results/{name}", env!("CARGO_MANIFEST_DIR"))
        }));
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    if !folder.is_dir() {
        panic!("the record's folder {} does not exist", folder.display());
    }
    path
}

/// Writes `record` to `path` whole or not at all (a temporary file beside
/// it, renamed over it).
pub fn write_record(path: &std::path::Path, record: &serde_json::Value) {
    let tmp = path.with_extension("json.tmp");
    let text = serde_json::to_string_pretty(record).unwrap() + "\n";
    std::fs::write(&tmp, text).unwrap_or_else(|e| panic!("writing {}: {e}", tmp.display()));
    std::fs::rename(&tmp, path)
        .unwrap_or_else(|e| panic!("renaming {} to {}: {e}", tmp.display(), path.display()));
    eprintln!("wrote {}", path.display());
}
