//! One forward pass per network at 256×256×28 (HSI-SDeCNN: one 7-band
//! 256² stack), median of 5 after a warm-up, on a 2-thread pool. Weights
//! come from `../shared/data` (or $CASSI_SHARED_DATA); without them the
//! benchmark says so and exits. Writes `bench/results/nets_forward.json`
//! (or $CASSI_BENCH_OUT). Each network runs in its own child process (the
//! benchmark re-executes itself), so a row's peak resident memory (VmHWM,
//! reset before each row through /proc/self/clear_refs) is that network's:
//! weights, inputs, activations, and what the allocator keeps cached.
//!
//! Run: `cargo bench -p cassi-nets --bench forward` (`-- mst_s` for one network)

#[path = "../tests/common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use cassi_nets::{
    HdNet, HsiSdecnn, MST_MASK_WIDTH, MST_SIZE, Mst, MstConfig, NETWORK_BANDS, Tensor,
};

const THREADS: usize = 2;
const NETWORKS: [&str; 4] = ["mst_s", "mst_l", "hdnet", "hsi_sdecnn"];
/// Set in a child process: where it writes its rows.
const CHILD_ENV: &str = "CASSI_NETS_FORWARD_CHILD";
const RUNS: usize = 5;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Deterministic values in [0, 1) (a xorshift), so runs are comparable.
fn uniform(n: usize, seed: u32) -> Vec<f32> {
    let mut s = seed.wrapping_mul(2_654_435_761) | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s >> 8) as f32 / (1u32 << 24) as f32
        })
        .collect()
}

fn time(mut f: impl FnMut()) -> (f64, Vec<f64>) {
    f(); // warm-up
    let runs: Vec<f64> = (0..RUNS)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    (median(runs.clone()), runs)
}

fn main() {
    let data = cassi_io::shared_data::default_dir();
    if !data.join("nets").is_dir() {
        eprintln!("no ../shared/data/nets (set CASSI_SHARED_DATA): nothing to time");
        return;
    }
    let only: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let wanted = |name: &str| only.is_empty() || only.iter().any(|o| o == name);
    if let Some(part) = std::env::var_os(CHILD_ENV) {
        let rows = run_networks(&data, &wanted);
        let text = serde_json::to_string(&rows).unwrap();
        std::fs::write(&part, text)
            .unwrap_or_else(|e| panic!("{}: {e}", Path::new(&part).display()));
        return;
    }
    let load_before = common::load_average();
    let exe = std::env::current_exe().expect("the benchmark's own path");
    let mut rows: Vec<serde_json::Value> = Vec::new();
    for name in NETWORKS.iter().filter(|n| wanted(n)) {
        let part = std::env::temp_dir().join(format!(
            "cassi-nets-forward-{}-{name}.json",
            std::process::id()
        ));
        let status = Command::new(&exe)
            .arg(name)
            .env(CHILD_ENV, &part)
            .status()
            .expect("the benchmark re-executes itself");
        assert!(status.success(), "{name}: child process failed");
        let text = std::fs::read_to_string(&part).unwrap();
        let _ = std::fs::remove_file(&part);
        let part_rows: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
        rows.extend(part_rows);
    }

    let out = std::env::var_os("CASSI_BENCH_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../bench/results/nets_forward.json")
        });
    let doc = serde_json::json!({
        "benchmark": "cassi-nets: one forward pass per network, batch 1, f32, CPU",
        "machine": { "cpu": common::cpu_model(), "threads": THREADS },
        // Other work on the machine inflates the times; the 1-minute load
        // average before and after the runs says how much there was.
        "load_average_1min": { "before": load_before, "after": common::load_average() },
        "protocol": format!("median of {RUNS} after 1 warm-up; rayon pool of {THREADS} threads"),
        "memory": "each network in its own process; peak_rss_mib: that process's VmHWM over a row's loading, warm-up and runs (reset per row, so a _reused row's peak includes what the full forward left in the allocator); rss_at_start_mib: VmRSS when the row started",
        "results": rows,
    });
    std::fs::write(&out, serde_json::to_string_pretty(&doc).unwrap() + "\n")
        .unwrap_or_else(|e| panic!("{}: {e}", out.display()));
    eprintln!("wrote {}", out.display());
}

/// The rows of the networks `wanted` selects, timed in this process.
fn run_networks(data: &Path, wanted: &dyn Fn(&str) -> bool) -> Vec<serde_json::Value> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(THREADS)
        .build()
        .expect("thread pool");

    let (n, bands) = (MST_SIZE, NETWORK_BANDS);
    let h = Tensor::new(vec![1, bands, n, n], uniform(bands * n * n, 1)).unwrap();
    let phi = Tensor::new(
        vec![1, bands, n, MST_MASK_WIDTH],
        uniform(bands * n * MST_MASK_WIDTH, 2),
    )
    .unwrap();
    let mut rows = Vec::new();
    let mut baseline = reset_peak_rss();
    let mut record = |name: &str, input: String, (med, runs): (f64, Vec<f64>)| {
        let peak = memory_mib("VmHWM");
        let cached = cassi_nets::cached_buffer_bytes() as f64 / (1 << 20) as f64;
        eprintln!(
            "{name}: median {med:.3} s over {RUNS} runs {runs:.3?}; peak RSS {peak:?} MiB (at start {baseline:?}; feature-map buffers kept for reuse {cached:.0} MiB)"
        );
        rows.push(serde_json::json!({
            "network": name, "input": input, "median_s": med, "runs_s": runs,
            "peak_rss_mib": peak, "rss_at_start_mib": baseline,
            "reuse_pool_mib_after": cached,
        }));
        baseline = reset_peak_rss();
    };

    for (name, file, config) in [
        ("mst_s", "nets/mst_s/mst_s.safetensors", MstConfig::SMALL),
        (
            "mst_l",
            "nets/mst_l/mst_l_seed0.safetensors",
            MstConfig::LARGE,
        ),
    ] {
        if wanted(name) {
            let net = Mst::load(data.join(file), config).unwrap_or_else(|e| panic!("{e}"));
            let t = pool.install(|| time(|| drop(net.forward(&h, &phi).unwrap())));
            record(
                name,
                format!("H 1×{bands}×{n}×{n}, Phi 1×{bands}×{n}×{MST_MASK_WIDTH}"),
                t,
            );
            // The mask half computed once (a fixed instrument), then per measurement.
            let guidance = pool.install(|| net.mask_guidance(&phi).unwrap());
            let t = pool.install(|| time(|| drop(net.forward_guided(&h, &guidance).unwrap())));
            record(
                &format!("{name}_mask_guidance_reused"),
                format!("H 1×{bands}×{n}×{n}"),
                t,
            );
        }
    }
    if wanted("hdnet") {
        let net = HdNet::load(data.join("nets/hdnet/hdnet_seed0.safetensors"))
            .unwrap_or_else(|e| panic!("{e}"));
        let t = pool.install(|| time(|| drop(net.forward(&h).unwrap())));
        record("hdnet", format!("H 1×{bands}×{n}×{n}"), t);
    }
    if wanted("hsi_sdecnn") {
        let net = HsiSdecnn::load(data.join("nets/hsi_sdecnn/hsi_sdecnn_seed0.safetensors"))
            .unwrap_or_else(|e| panic!("{e}"));
        let stack = Tensor::new(vec![1, 7, n, n], uniform(7 * n * n, 3)).unwrap();
        let sigma = Tensor::new(vec![1, 1, 1, 1], vec![10.0 / 255.0]).unwrap();
        let t = pool.install(|| time(|| drop(net.forward(&stack, &sigma).unwrap())));
        record("hsi_sdecnn", format!("1×7×{n}×{n} (one band of a cube)"), t);
    }

    rows
}

/// Resets the peak resident set size to the current one (Linux 4.0+:
/// "5" to /proc/self/clear_refs) and returns the current one, MiB.
fn reset_peak_rss() -> Option<f64> {
    std::fs::write("/proc/self/clear_refs", "5").ok()?;
    memory_mib("VmRSS")
}

/// A /proc/self/status memory line (kB) in MiB.
fn memory_mib(field: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
