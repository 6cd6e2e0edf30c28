//! MST-S (official weights) against GAP-TV on the 10 CAVE scenes of
//! ../shared/data: noise-free nominal measurements (rounded model, TSA
//! simulation mask), PSNR / SSIM / SAM per scene and the times, on a
//! 2-thread pool. Writes `bench/results/nets_cave.json` (or
//! $CASSI_BENCH_OUT). The `mst_s_cave` test asserts the margin on two scenes.
//!
//! Run: `cargo bench -p cassi-nets --bench cave`

#[path = "../tests/common/mod.rs"]
mod common;

use std::path::PathBuf;

use common::cave::{gap_tv_and_network, scenes, tsa_mask};

const THREADS: usize = 2;

fn main() {
    let data = cassi_io::shared_data::default_dir();
    if !data.join("scenes").is_dir() {
        eprintln!("no shared data with scenes (set CASSI_SHARED_DATA): nothing to run");
        return;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(THREADS)
        .build()
        .expect("thread pool");
    let load_before = common::load_average();
    let mask = tsa_mask(&data);
    let net = cassi_nets::Network::load(
        cassi_core::recon::MethodId::MstS,
        data.join("weights/mst_s.pth"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut rows = Vec::new();
    let (mut sum_gap, mut sum_mst) = (0.0, 0.0);
    let files = scenes(&data);
    for scene in &files {
        let name = scene.file_stem().unwrap().to_string_lossy().into_owned();
        let (gap, mst) = pool.install(|| gap_tv_and_network(scene, &mask, &net));
        eprintln!(
            "{name:<28} GAP-TV {:.2} dB ({:.1} s)   MST-S {:.2} dB ({:.2} s)",
            gap.metrics.psnr, gap.seconds, mst.metrics.psnr, mst.seconds
        );
        sum_gap += gap.metrics.psnr;
        sum_mst += mst.metrics.psnr;
        rows.push(serde_json::json!({
            "scene": name,
            "gap_tv": { "psnr": gap.metrics.psnr, "ssim": gap.metrics.ssim,
                        "sam_deg": gap.metrics.sam_deg, "seconds": gap.seconds },
            "mst_s": { "psnr": mst.metrics.psnr, "ssim": mst.metrics.ssim,
                       "sam_deg": mst.metrics.sam_deg, "seconds": mst.seconds },
        }));
    }
    let n = files.len().max(1) as f64;
    eprintln!(
        "mean PSNR: GAP-TV {:.2} dB, MST-S {:.2} dB",
        sum_gap / n,
        sum_mst / n
    );
    let out = std::env::var_os("CASSI_BENCH_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../bench/results/nets_cave.json")
        });
    let doc = serde_json::json!({
        "benchmark": "MST-S (official weights) vs GAP-TV on CAVE, noise-free nominal measurements",
        "setup": "TSA simulation mask 256×256, 28 bands, stride 2, rounded model, no noise; \
                  GAP-TV with cassi's tuned defaults (100 iterations, λ 0.07, 5 TV iterations); \
                  both clipped to [0, 1]; PSNR peak 1 over the cube, SSIM band mean, SAM degrees",
        "machine": { "cpu": common::cpu_model(), "threads": THREADS },
        "load_average_1min": { "before": load_before, "after": common::load_average() },
        "mean_psnr": { "gap_tv": sum_gap / n, "mst_s": sum_mst / n },
        "scenes": rows,
    });
    std::fs::write(&out, serde_json::to_string_pretty(&doc).unwrap() + "\n")
        .unwrap_or_else(|e| panic!("{}: {e}", out.display()));
    eprintln!("wrote {}", out.display());
}
