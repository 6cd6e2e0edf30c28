//! GAP-TV benchmark: accuracy on the 10 CAVE scenes (TSA mask, stride 2, no
//! mismatch, no noise) and speed, side by side with the NumPy +
//! scikit-image reference `bench/gap_tv_reference.py` run on the same machine;
//! plus 660×660×28 time and the peak memory of each size in its own process.
//!
//! Run: `cargo run --release -p cassi-bench --bin gap-tv [-- --skip-reference]`
//! (the reference needs a Python with numpy, scipy and scikit-image:
//! $CASSI_PYTHON, default `python3`). Writes `bench/results/gap_tv.json`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, bail};
use cassi_bench::{median, peak_rss_mib, shared_data};
use cassi_core::Mismatch;
use cassi_core::metrics::psnr;
use cassi_core::optics::{CassiOperator, DispersionModel};
use cassi_core::recon::{Method, Model};
use cassi_core::solvers::Silent;
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_eval::machine::Machine;

/// The constant TV weight of a GAP-TV method (the reference runs the same).
fn gap_weight(m: &Method) -> f32 {
    match m {
        Method::GapTv { gap, .. } => gap.strength.at(0, gap.iterations),
        _ => f32::NAN,
    }
}

/// One solve on a synthetic scene of `size`², in this process: (seconds, peak MiB).
fn one_size(size: usize) -> anyhow::Result<serde_json::Value> {
    let base = peak_rss_mib().unwrap_or(f64::NAN);
    let scene = synthetic_scene(&SceneSpec {
        rows: size,
        cols: size,
        ..SceneSpec::default()
    })?;
    let mask = random_binary_mask(size, size, 0.5, 1)?;
    let nominal = Mismatch::nominal(2.0);
    let y = CassiOperator::with_mismatch(&mask, 28, &nominal, DispersionModel::Rounded)?
        .forward(&scene)?;
    let before_solve = peak_rss_mib().unwrap_or(f64::NAN);
    let method = Method::by_name("gap-tv")?;
    let mut times = Vec::new();
    for _ in 0..3 {
        let t0 = Instant::now();
        let model = Model::new(&mask, 28, 2.0, nominal, DispersionModel::Rounded)?;
        let r = method.solve(&y, &model, &mut Silent)?;
        times.push(t0.elapsed().as_secs_f64());
        std::hint::black_box(r);
    }
    let peak = peak_rss_mib().unwrap_or(f64::NAN);
    let cube_mib = (28 * size * size * 4) as f64 / (1024.0 * 1024.0);
    Ok(serde_json::json!({
        "size": format!("{size}x{size}x28"),
        "seconds_median": median(times),
        "peak_rss_mib": peak,
        "rss_before_solve_mib": before_solve,
        "rss_at_start_mib": base,
        "cube_mib": cube_mib,
        // inputs (scene, y, mask) are held by the benchmark, not the solver
        "solver_peak_in_cubes": (peak - before_solve) / cube_mib,
    }))
}

fn rust_scenes(scenes: &[PathBuf], mask_path: &Path) -> anyhow::Result<serde_json::Value> {
    let mask = cassi_io::load_frame(mask_path, Some("mask"))?;
    let method = Method::by_name("gap-tv")?;
    let nominal = Mismatch::nominal(2.0);
    let mut rows = Vec::new();
    for path in scenes {
        let truth = cassi_io::load_cube(path, None, cassi_io::CubeLayout::Auto)?;
        let op =
            CassiOperator::with_mismatch(&mask, truth.bands(), &nominal, DispersionModel::Rounded)?;
        let y = op.forward(&truth)?;
        let t0 = Instant::now();
        let model = Model::new(&mask, truth.bands(), 2.0, nominal, DispersionModel::Rounded)?;
        let r = method.solve(&y, &model, &mut Silent)?;
        let secs = t0.elapsed().as_secs_f64();
        let p = psnr(&truth, &r.cube.clipped_to_unit())?;
        let name = cassi_bench::scene_name(path);
        eprintln!("cassi  {name:<32} {p:7.3} dB {secs:6.3} s");
        rows.push(serde_json::json!({ "scene": name, "psnr": p, "seconds": secs }));
    }
    let mean = rows
        .iter()
        .map(|r| r["psnr"].as_f64().unwrap_or(f64::NAN))
        .sum::<f64>()
        / rows.len() as f64;
    let med = median(
        rows.iter()
            .map(|r| r["seconds"].as_f64().unwrap_or(f64::NAN))
            .collect(),
    );
    Ok(
        serde_json::json!({ "method": method, "scenes": rows, "mean_psnr": mean, "median_seconds": med }),
    )
}

fn main() -> anyhow::Result<()> {
    cassi_bench::check_arguments(
        "gap-tv [--skip-reference] (writes bench/results/gap_tv.json or $CASSI_BENCH_OUT; \
         --one-size N is its own child run)",
        &["--skip-reference", "--one-size"],
    )?;
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--one-size") {
        let size: usize = args.get(i + 1).context("--one-size N")?.parse()?;
        println!("{}", one_size(size)?);
        return Ok(());
    }
    // the record's path, its folder made before the work
    let path = cassi_bench::bench_out("gap_tv.json")?;
    let data = shared_data();
    let mask_path = data.join("masks/tsa_simu_mask256.mat");
    let scenes = cassi_bench::cave_scenes(&data)?;

    let ours = rust_scenes(&scenes, &mask_path)?;
    let exe = std::env::current_exe()?;
    let mut sizes = Vec::new();
    for size in [256, 660] {
        let out = Command::new(&exe)
            .args(["--one-size", &size.to_string()])
            .output()?;
        if !out.status.success() {
            bail!("size {size}: {}", String::from_utf8_lossy(&out.stderr));
        }
        let v: serde_json::Value = serde_json::from_slice(&out.stdout)?;
        eprintln!("cassi  {size}x{size}x28: {}", v);
        sizes.push(v);
    }

    let reference = if args.iter().any(|a| a == "--skip-reference") {
        serde_json::Value::Null
    } else {
        let python = std::env::var("CASSI_PYTHON").unwrap_or_else(|_| "python3".into());
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../bench/gap_tv_reference.py");
        let out_json = std::env::temp_dir().join("cassi_gap_tv_reference.json");
        let status = Command::new(&python)
            .arg(&script)
            .args([
                "--scenes",
                &data.join("scenes").to_string_lossy(),
                "--mask",
                &mask_path.to_string_lossy(),
            ])
            .args(["--out", &out_json.to_string_lossy()])
            .args([
                "--weight",
                &gap_weight(&Method::by_name("gap-tv")?).to_string(),
            ])
            .env("OMP_NUM_THREADS", "2")
            .env("OPENBLAS_NUM_THREADS", "2")
            .status()
            .with_context(|| format!("running {python} {}", script.display()))?;
        if !status.success() {
            bail!(
                "the NumPy reference failed (needs numpy, scipy, scikit-image; set CASSI_PYTHON)"
            );
        }
        let text = std::fs::read_to_string(&out_json)?;
        // kept apart too: the accuracy test compares against it
        let kept =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../bench/results/gap_tv_reference.json");
        std::fs::write(kept, &text)?;
        serde_json::from_str(&text)?
    };
    let comparison = if reference.is_null() {
        serde_json::Value::Null
    } else {
        let mean_diff = ours["mean_psnr"].as_f64().unwrap_or(f64::NAN)
            - reference["mean_psnr"].as_f64().unwrap_or(f64::NAN);
        let speedup = reference["median_seconds"].as_f64().unwrap_or(f64::NAN)
            / ours["median_seconds"].as_f64().unwrap_or(f64::NAN);
        serde_json::json!({ "mean_psnr_difference_db": mean_diff, "speedup_vs_reference": speedup })
    };
    let sizes_ratio = sizes[1]["seconds_median"].as_f64().unwrap_or(f64::NAN)
        / sizes[0]["seconds_median"].as_f64().unwrap_or(f64::NAN);
    let out = serde_json::json!({
        "benchmark": "GAP-TV on 10 CAVE scenes, TSA simulation mask, stride 2, no mismatch, no noise",
        "machine": Machine::this(),
        "cassi": ours,
        "reference": reference,
        "comparison": comparison,
        "sizes": sizes,
        "time_ratio_660_vs_256": sizes_ratio,
    });
    cassi_bench::write_record(&path, &out)?;
    eprintln!(
        "{}\nwrote {path}",
        serde_json::to_string_pretty(&out["comparison"])?
    );
    Ok(())
}
