//! `cassi eval`: the four-scenario study over a set of scenes.

use std::path::PathBuf;

use anyhow::Context;
use cassi_core::Instrument;
use cassi_core::Mismatch;
use cassi_core::calib::{PRESET_NAMES, Preset};
use cassi_core::limits::check_elements;
use cassi_core::metrics::SSIM_WIN;
use cassi_core::optics::NoiseModel;
use cassi_core::recon::registry::names_of;
use cassi_core::recon::{Method, MethodId, MethodKind};
use cassi_eval::jobs::eval::{
    EvalMode, EvalOutcome, EvalPlan, SceneSet, declare_outputs, mask_from_file, random_study_mask,
    run_eval,
};
use cassi_eval::learned::check_stride;
use cassi_eval::method::{LearnedMethod, StudyMethod};
use cassi_eval::protocol::Study;
use cassi_eval::report::REPORT_FILE;
use cassi_eval::shard::Shard;
use cassi_eval::study::SceneSource;
use cassi_eval::sweep::scaled_mismatch;
use cassi_eval::weights::{NETS_BUILT, parse_weight_flags, resolve_weights};
use cassi_io::{CheckedSet, OutputSet};
use clap::Args;

use super::inputs::{MismatchArgs, NoiseArgs};
use crate::observer::CliObserver;
use crate::report::Reporter;

#[derive(Args)]
pub struct EvalArgs {
    /// Folder of scene cubes (.npy, .npz, .mat; values in [0, 1]).
    #[arg(
        long,
        conflicts_with = "synthetic",
        required_unless_present = "synthetic"
    )]
    pub scenes: Option<PathBuf>,
    /// Use embedded synthetic scenes instead (seeds 0, 1, …).
    #[arg(long)]
    pub synthetic: bool,
    /// Synthetic scenes: how many.
    #[arg(long, default_value_t = 1)]
    pub count: usize,
    /// Synthetic scenes: rows and cols.
    #[arg(long, default_value_t = 256)]
    pub size: usize,
    /// At most this many scenes (in name order).
    #[arg(long)]
    pub limit: Option<usize>,
    /// The nominal coded aperture (default with --synthetic: a random binary mask).
    #[arg(long, required_unless_present = "synthetic")]
    pub mask: Option<PathBuf>,
    /// Variable name inside the mask file.
    #[arg(long)]
    pub mask_var: Option<String>,
    /// Reconstruction methods, comma-separated: solvers (gap-tv, admm-tv,
    /// pnp-tv) and, in a build with `--features nets`, learned methods
    /// (mst-s, mst-l, hdnet, pnp-hsicnn; they need weights).
    #[arg(long, default_value = "gap-tv", value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Weights of one learned method, METHOD=FILE (.pth state dict or
    /// .safetensors); repeat the flag for several methods.
    #[arg(long = "weights", value_name = "METHOD=FILE")]
    pub weights: Vec<String>,
    /// A folder of weights, searched as <method>.pth / .safetensors with -
    /// or _ (mst_s.pth, mst-l.safetensors, hdnet.pth; pnp-hsicnn also
    /// deep_denoiser.pth); --weights overrides it per method.
    #[arg(long)]
    pub weights_dir: Option<PathBuf>,
    /// Solver iterations, PnP-HSICNN included (default: each method's own;
    /// networks have none).
    #[arg(long, value_parser = super::inputs::parse_iterations)]
    pub iterations: Option<usize>,
    /// Calibration preset.
    #[arg(long, default_value = "default", value_parser = PRESET_NAMES)]
    pub preset: String,
    /// The true mismatch: the paper's (dx 1.5, dy 1.0, θ 0.3°, a1 2.04,
    /// α 0.5°), single values overridden by these flags.
    #[command(flatten)]
    pub mismatch: MismatchArgs,
    #[command(flatten)]
    pub noise: NoiseArgs,
    /// Nominal dispersion stride, px per band.
    #[arg(long, default_value_t = 2.0)]
    pub stride: f64,
    /// Output folder (per-scene results, tables, report).
    #[arg(long, short, default_value = "cassi-eval")]
    pub out: PathBuf,
    /// Skip scenes whose result from the same study is already in --out.
    #[arg(long)]
    pub resume: bool,
    /// Also run the study at these multiples of the paper's mismatch (all
    /// five parameters scaled), e.g. 0.25,0.5,0.75,1,1.5,2,3.
    #[arg(long, value_delimiter = ',')]
    pub sensitivity: Vec<f64>,
    /// Also compare, per preset, the search stages alone with the full
    /// pipeline and the oracle.
    #[arg(long)]
    pub ablation: bool,
    /// Presets the sweeps run (default: --preset).
    #[arg(long, value_delimiter = ',', value_parser = PRESET_NAMES)]
    pub sweep_presets: Vec<String>,
    /// Run only shard K of N (K from 0): scenes K, K + N, K + 2N, … (each
    /// keeps its noise seed), into --out's shards/K-of-N/; no report. Run
    /// every shard with otherwise the same flags (in any order, anywhere
    /// that sees --out), then `--merge N`.
    #[arg(long, value_name = "K/N", value_parser = Shard::parse, conflicts_with = "merge")]
    pub shard: Option<Shard>,
    /// Write the report of a study whose N shards have finished (same flags
    /// as the shards): the same files one process would have written.
    #[arg(long, value_name = "N")]
    pub merge: Option<usize>,
}

impl EvalArgs {
    fn mode(&self) -> EvalMode {
        match (self.shard, self.merge) {
            (Some(shard), _) => EvalMode::Shard(shard),
            (None, Some(count)) => EvalMode::Merge { count },
            (None, None) => EvalMode::Whole,
        }
    }
}

/// The study's methods: solvers by name, learned methods with their
/// weights, loaded here, once, before any scene runs (the study reuses them).
fn study_methods(args: &EvalArgs) -> anyhow::Result<Vec<StudyMethod>> {
    let names: Vec<String> = args.methods.iter().map(|m| m.trim().to_string()).collect();
    let given = parse_weight_flags(&args.weights, &names)?;
    names
        .iter()
        .map(|name| {
            let id = MethodId::parse(name).map_err(|_| {
                let list = |kinds: &[MethodKind]| {
                    kinds
                        .iter()
                        .flat_map(|&k| names_of(k))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                anyhow::anyhow!(
                    "--methods: unknown method '{name}' (solvers: {}; learned, with weights: {})",
                    list(&[MethodKind::Iterative]),
                    list(&[MethodKind::Network, MethodKind::LearnedPnp])
                )
            })?;
            if let Some(method) = Method::defaults(id) {
                return Ok(method.with_overrides(args.iterations, None).into());
            }
            if !NETS_BUILT {
                anyhow::bail!(
                    "--methods {name}: this cassi was built without the deep networks; \
                     rebuild it with `cargo build --release -p cassi-cli --features nets`"
                );
            }
            let weights = resolve_weights(id, &given, args.weights_dir.as_deref())?;
            let iterations = args.iterations.filter(|_| id.kind().has_iterations());
            let learned = LearnedMethod::new(id, weights, iterations);
            check_stride(id, args.stride)?;
            Ok(StudyMethod::Learned(learned.load()?))
        })
        .collect()
}

/// Refuses flags that could only fail later, after work: no scenes, scenes
/// too small to score, sweep scales that are no mismatch.
fn check_flags(args: &EvalArgs) -> anyhow::Result<()> {
    if args.synthetic {
        if args.count == 0 {
            anyhow::bail!("--count 0: a study needs at least one scene");
        }
        if args.size < SSIM_WIN {
            anyhow::bail!(
                "--size {}: scenes must be at least {SSIM_WIN}×{SSIM_WIN} pixels (SSIM's \
                 {SSIM_WIN}×{SSIM_WIN} window)",
                args.size
            );
        }
        let bands = Instrument::default().bands;
        check_elements(
            "a synthetic scene",
            &[bands, args.size, args.size],
            &format!("--size {}", args.size),
        )?;
    }
    if args.limit == Some(0) {
        anyhow::bail!("--limit 0: a study needs at least one scene");
    }
    for &s in &args.sensitivity {
        if !(s.is_finite() && s > 0.0) {
            anyhow::bail!(
                "--sensitivity {s}: each scale is a positive multiple of the paper's mismatch"
            );
        }
        scaled_mismatch(s, args.stride)
            .validate()
            .with_context(|| format!("--sensitivity {s}: the scaled mismatch"))?;
    }
    Ok(())
}

/// The files the study reads and writes, checked before any work: the
/// report files in --out, and its folders written scene by scene (scenes/,
/// figures/, sensitivity/), which must hold no input.
fn check_files(args: &EvalArgs, scenes: &[SceneSource]) -> anyhow::Result<CheckedSet> {
    let mut set = OutputSet::new();
    for scene in scenes {
        if let SceneSource::File { path } = scene {
            set.input("a scene of --scenes", path);
        }
    }
    if let Some(p) = &args.mask {
        set.input("--mask", p);
    }
    let names: Vec<String> = args.methods.iter().map(|m| m.trim().to_string()).collect();
    for (_, file) in parse_weight_flags(&args.weights, &names)? {
        set.input("--weights", file);
    }
    if let Some(dir) = &args.weights_dir
        && let Ok(entries) = std::fs::read_dir(dir)
    {
        for path in entries.flatten().map(|e| e.path()).filter(|p| p.is_file()) {
            set.input("a file of --weights-dir", path);
        }
    }
    declare_outputs(
        &mut set,
        &args.out,
        !args.sensitivity.is_empty(),
        args.mode(),
    );
    Ok(set.check()?)
}

pub fn run(args: &EvalArgs, reporter: &Reporter) -> anyhow::Result<()> {
    check_flags(args)?;
    let scene_set = match &args.scenes {
        Some(dir) => SceneSet::folder(dir)?,
        None => SceneSet::synthetic(args.count, args.size),
    };
    // every listed scene is protected, read or not (--limit)
    let checked = check_files(args, &scene_set.scenes)?;
    let methods = study_methods(args)?;
    // the paper's mismatch, single values overridden by the flags
    let mismatch = args.mismatch.over(Mismatch::paper());
    mismatch.validate().context("mismatch parameters")?;
    let noise = args.noise.noise()?.unwrap_or(NoiseModel {
        photon_peak: None,
        read_noise: 0.0,
        seed: 0,
    });
    let SceneSet {
        scenes,
        label: scenes_label,
    } = scene_set.limit(args.limit);
    let (mask, mask_label) = match &args.mask {
        Some(p) => mask_from_file(p, args.mask_var.as_deref())?,
        None => random_study_mask(args.size)?,
    };
    let study = Study {
        mismatch,
        instrument: args.mismatch.model,
        noise,
        preset: Preset::by_name(&args.preset, args.stride)?,
        methods,
        stride: args.stride,
    };
    let sweep_presets: Vec<Preset> = if args.sweep_presets.is_empty() {
        vec![study.preset.clone()]
    } else {
        args.sweep_presets
            .iter()
            .map(|p| Preset::by_name(p, args.stride))
            .collect::<Result<_, _>>()?
    };
    let plan = EvalPlan {
        study,
        scenes,
        mask,
        scenes_label,
        mask_label,
        out: args.out.clone(),
        resume: args.resume,
        sensitivity: args.sensitivity.clone(),
        ablation: args.ablation,
        sweep_presets,
        mode: args.mode(),
    };
    plan.check()?;
    let EvalOutcome {
        summary, results, ..
    } = run_eval(&plan, checked, &mut CliObserver::new(reporter))?;
    if let EvalMode::Shard(shard) = plan.mode {
        reporter.say(&format!(
            "shard {shard}: {} scene result(s) in {}; when every shard has finished, run the \
             same command with --merge {} instead of --shard",
            results.len(),
            shard.folder(&args.out).display(),
            shard.count()
        ));
        reporter.emit(&serde_json::to_value(&summary)?);
        return Ok(());
    }
    let mut text = String::from("\n");
    text += &cassi_eval::tables::main_table(&summary);
    text += &format!(
        "\nparameter RMSE: {}; calibration median {:.1} s; study {:.1} s\nreport: {}",
        summary.parameter_rmse.format_all().replace('+', ""),
        summary.calibration_seconds_median,
        summary.total_seconds,
        args.out.join(REPORT_FILE).display()
    );
    reporter.say(&text);
    reporter.emit(&serde_json::to_value(&summary)?);
    Ok(())
}
