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

/// Writes `record` to `bench/results/<name>` (or $CASSI_BENCH_OUT).
pub fn write_record(name: &str, record: &serde_json::Value) {
    let path = std::env::var("CASSI_BENCH_OUT")
        .unwrap_or_else(|_| format!("{}/../../bench/results/{name}", env!("CARGO_MANIFEST_DIR")));
    std::fs::write(&path, serde_json::to_string_pretty(record).unwrap() + "\n").unwrap();
    eprintln!("wrote {path}");
}
