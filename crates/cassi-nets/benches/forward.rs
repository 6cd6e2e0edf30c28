//! One forward pass per network at 256×256×28 (HSI-SDeCNN: one 7-band
//! 256² stack), median of 5 after a warm-up, on a 2-thread pool. Weights
//! come from `../shared/data` (or $CASSI_SHARED_DATA); without them the
//! benchmark says so and exits. Writes `bench/results/nets_forward.json`
//! (or $CASSI_BENCH_OUT).
//!
//! Run: `cargo bench -p cassi-nets --bench forward` (`-- mst_s` for one network)

use std::path::PathBuf;
use std::time::Instant;

use cassi_nets::{HdNet, HsiSdecnn, MST_BANDS, MST_MASK_WIDTH, MST_SIZE, Mst, MstConfig, Tensor};

const THREADS: usize = 2;
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
    let data = std::env::var_os("CASSI_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    if !data.join("nets").is_dir() {
        eprintln!(
            "no shared data at {} (set CASSI_SHARED_DATA): nothing to time",
            data.display()
        );
        return;
    }
    let only: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let wanted = |name: &str| only.is_empty() || only.iter().any(|o| o == name);
    let load_before = load_average();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(THREADS)
        .build()
        .expect("thread pool");

    let (n, bands) = (MST_SIZE, MST_BANDS);
    let h = Tensor::new(vec![1, bands, n, n], uniform(bands * n * n, 1)).unwrap();
    let phi = Tensor::new(
        vec![1, bands, n, MST_MASK_WIDTH],
        uniform(bands * n * MST_MASK_WIDTH, 2),
    )
    .unwrap();
    let mut rows = Vec::new();
    let mut record = |name: &str, input: String, (med, runs): (f64, Vec<f64>)| {
        eprintln!("{name}: median {med:.3} s over {RUNS} runs {runs:.3?}");
        rows.push(serde_json::json!({
            "network": name, "input": input, "median_s": med, "runs_s": runs,
        }));
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

    let out = std::env::var_os("CASSI_BENCH_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../bench/results/nets_forward.json")
        });
    let doc = serde_json::json!({
        "benchmark": "cassi-nets: one forward pass per network, batch 1, f32, CPU",
        "machine": { "cpu": cpu_model(), "threads": THREADS },
        // Other work on the machine inflates the times; the 1-minute load
        // average before and after the runs says how much there was.
        "load_average_1min": { "before": load_before, "after": load_average() },
        "protocol": format!("median of {RUNS} after 1 warm-up; rayon pool of {THREADS} threads"),
        "results": rows,
    });
    std::fs::write(&out, serde_json::to_string_pretty(&doc).unwrap() + "\n")
        .unwrap_or_else(|e| panic!("{}: {e}", out.display()));
    eprintln!("wrote {}", out.display());
}

fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}
