//! The whole evaluation (`cassi eval`): the four-scenario study over a set
//! of scenes, the optional sweeps, then the summary, tables, report and
//! figures, all replaced together or not at all.

use std::path::{Path, PathBuf};

use anyhow::Context;
use cassi_core::calib::Preset;
use cassi_core::metrics::SSIM_WIN;
use cassi_core::optics::{validate_mask, validate_mismatch_for_mask};
use cassi_core::synth::random_binary_mask;
use cassi_core::{Instrument, Mask};
use cassi_io::{CheckedSet, OutputSet, Staging};

use super::JobObserver;
use crate::learned::check_shape;
use crate::method::StudyMethod;
use crate::protocol::{SceneProgress, SceneResult, Study};
use crate::report::{STUDY_FILES, Setup, write_all};
use crate::shard::Shard;
use crate::study::{
    Event, RunOptions, SceneSource, copy_tree, promote_pending, remove_pending, run_study,
    scene_path, scenes_in, stored_result,
};
use crate::study_figures::write_qualitative;
use crate::summary::{Summary, summarize};
use crate::sweep::{ablation, scaled_mismatch, sensitivity};
use crate::sweep_rows::Sweeps;

/// One evaluation, fully decided: what runs, on what, and where it goes.
pub struct EvalPlan {
    pub study: Study,
    pub scenes: Vec<SceneSource>,
    pub mask: Mask,
    /// How the report names the scenes and the mask.
    pub scenes_label: String,
    pub mask_label: String,
    /// The output folder (per-scene results, tables, report, figures).
    pub out: PathBuf,
    /// Reuse scene results of the same study already in `out`.
    pub resume: bool,
    /// Also run the study at these multiples of the paper's mismatch.
    pub sensitivity: Vec<f64>,
    /// Also compare the search stages alone with the full pipeline.
    pub ablation: bool,
    /// The presets the sweeps run.
    pub sweep_presets: Vec<Preset>,
    /// The whole study, one shard of it, or the merge of finished shards.
    pub mode: EvalMode,
}

/// Which part of an evaluation one run does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EvalMode {
    /// Every scene, then the report.
    Whole,
    /// One shard's scenes into [`Shard::folder`]; no report (the merge
    /// writes it).
    Shard(Shard),
    /// The report of a study whose `count` shards have finished, from their
    /// folders: the same files one process would have written.
    Merge { count: usize },
}

/// What an evaluation produced (its files are in the plan's `out`).
pub struct EvalOutcome {
    pub results: Vec<SceneResult>,
    pub summary: Summary,
    pub sweeps: Sweeps,
}

/// The scenes of a study and how its report names them.
pub struct SceneSet {
    pub scenes: Vec<SceneSource>,
    pub label: String,
}

impl SceneSet {
    /// Every scene cube in `dir` (.npy, .npz, .mat), in name order.
    pub fn folder(dir: &Path) -> anyhow::Result<Self> {
        Ok(Self {
            scenes: scenes_in(dir)?,
            label: format!("`{}`", dir.display()),
        })
    }

    /// `count` embedded synthetic scenes of `size`×`size`×28, seeds 0, 1, ….
    pub fn synthetic(count: usize, size: usize) -> Self {
        let wavelengths_nm = Instrument::default().wavelengths_nm;
        Self {
            scenes: (0..count as u64)
                .map(|seed| SceneSource::Synthetic {
                    seed,
                    rows: size,
                    cols: size,
                    wavelengths_nm: wavelengths_nm.clone(),
                })
                .collect(),
            label: format!("embedded synthetic {size}×{size}×28, seeds 0…"),
        }
    }

    /// At most the first `n` scenes.
    pub fn limit(mut self, n: Option<usize>) -> Self {
        if let Some(n) = n {
            self.scenes.truncate(n);
        }
        self
    }
}

/// The study's nominal mask from `file` (variable `var`), checked, and how
/// the report names it.
pub fn mask_from_file(file: &Path, var: Option<&str>) -> anyhow::Result<(Mask, String)> {
    let mask = cassi_io::load_frame(file, var)?;
    validate_mask(&mask, &format!("mask {}", file.display()))?;
    Ok((mask, format!("`{}`", file.display())))
}

/// The mask a synthetic study uses when given none: random binary
/// `size`×`size`, 50 % open, seed 1.
pub fn random_study_mask(size: usize) -> anyhow::Result<(Mask, String)> {
    Ok((
        random_binary_mask(size, size, 0.5, 1)?,
        format!("random binary {size}×{size}, 50 % open, seed 1"),
    ))
}

/// Declares the files and folders an evaluation into `out` writes: the
/// report files and the folders written scene by scene (which must hold no
/// input); a shard writes only its own folder's.
pub fn declare_outputs(set: &mut OutputSet, out: &Path, with_sensitivity: bool, mode: EvalMode) {
    if let EvalMode::Shard(shard) = mode {
        let folder = shard.folder(out);
        set.output_dir(format!("shard {shard}'s scenes/"), folder.join("scenes"))
            .output_dir(format!("shard {shard}'s figures/"), folder.join("figures"));
        return;
    }
    for file in STUDY_FILES {
        set.output(format!("--out's {file}"), out.join(file));
    }
    set.output_dir("--out's scenes/", out.join("scenes"))
        .output_dir("--out's figures/", out.join("figures"));
    if with_sensitivity {
        set.output_dir("--out's sensitivity/", out.join("sensitivity"));
    }
}

impl EvalPlan {
    /// Refuses, before any work, a mask too small to score, a mismatch (the
    /// study's, or any sweep's) that moves the mask off itself, and a
    /// learned method whose network cannot take the scenes' shape.
    pub fn check(&self) -> anyhow::Result<()> {
        let (mask, label) = (&self.mask, &self.mask_label);
        if self.mode != EvalMode::Whole && (!self.sensitivity.is_empty() || self.ablation) {
            anyhow::bail!(
                "--sensitivity and --ablation run in one process: they are not sharded or \
                 merged (run them without --shard and --merge)"
            );
        }
        if let EvalMode::Merge { count: 0 } = self.mode {
            anyhow::bail!("--merge 0: a study has at least one shard");
        }
        if mask.rows() < SSIM_WIN || mask.cols() < SSIM_WIN {
            anyhow::bail!(
                "mask {label} is {}×{}: scenes must be at least {SSIM_WIN}×{SSIM_WIN} pixels \
                 (SSIM's window)",
                mask.rows(),
                mask.cols()
            );
        }
        validate_mismatch_for_mask(&self.study.mismatch, mask.rows(), mask.cols())
            .with_context(|| format!("the mismatch, with mask {label}"))?;
        for &s in &self.sensitivity {
            validate_mismatch_for_mask(
                &scaled_mismatch(s, self.study.stride),
                mask.rows(),
                mask.cols(),
            )
            .with_context(|| format!("--sensitivity {s}, with mask {label}"))?;
        }
        let from_files = self
            .scenes
            .iter()
            .any(|s| matches!(s, SceneSource::File { .. }));
        for method in &self.study.methods {
            if let StudyMethod::Learned(l) = method {
                let bands = match (from_files, l.method.spec().shape.bands) {
                    // the scenes' band count is checked as each loads
                    (true, Some(trained)) => trained,
                    _ => Instrument::default().wavelengths_nm.len(),
                };
                check_shape(l.method, bands, mask.rows(), mask.cols())
                    .with_context(|| format!("--methods {} with mask {label}", l.method))?;
            }
        }
        Ok(())
    }
}

/// Runs the plan: the study scene by scene (each result on disk as it is
/// made, so an interrupted run resumes), the sweeps, then every report file
/// written together. `checked` holds the output paths checked before any
/// work (see [`declare_outputs`]).
pub fn run_eval(
    plan: &EvalPlan,
    checked: CheckedSet,
    observer: &mut dyn JobObserver,
) -> anyhow::Result<EvalOutcome> {
    let results = match plan.mode {
        EvalMode::Whole => run_scenes(plan, &plan.out, None, observer)?,
        EvalMode::Shard(shard) => {
            let folder = shard.folder(&plan.out);
            let results = run_scenes(plan, &folder, Some(shard), observer)?;
            // the shard's scene records and figures, all or none
            observer.checkpoint()?;
            let staging = checked.begin()?;
            let pending = promote_pending(&folder)?;
            observer.checkpoint()?;
            staging.commit()?;
            remove_pending(&pending)?;
            return Ok(EvalOutcome {
                summary: summarize(&results),
                results,
                sweeps: Sweeps::default(),
            });
        }
        EvalMode::Merge { count } => {
            let results = read_shards(plan, count, observer)?;
            let staging = checked.begin()?;
            copy_shards(plan, count, &results)?;
            return write_report(plan, results, Sweeps::default(), staging, observer);
        }
    };
    let sweeps = run_sweeps(plan, observer)?;
    // the summary, tables, report and figures: all replaced, or none
    observer.checkpoint()?;
    let staging = checked.begin()?;
    // the study's scene records and first-scene figures join the set
    let pending = promote_pending(&plan.out)?;
    let outcome = write_report(plan, results, sweeps, staging, observer)?;
    remove_pending(&pending)?;
    Ok(outcome)
}

/// The study's scenes (or one shard's) into `out`, each result on disk as
/// it is made.
fn run_scenes(
    plan: &EvalPlan,
    out: &Path,
    shard: Option<Shard>,
    observer: &mut dyn JobObserver,
) -> anyhow::Result<Vec<SceneResult>> {
    let study = &plan.study;
    let steps_per_scene = study.steps_per_scene();
    let held = (0..plan.scenes.len())
        .filter(|&i| shard.is_none_or(|s| s.holds(i)))
        .count() as u64;
    observer.progress_started("evaluating", steps_per_scene * held);
    let mut done = 0u64;
    let results = run_study(
        study,
        &plan.scenes,
        &plan.mask,
        out,
        RunOptions {
            resume: plan.resume,
            shard,
            qualitative: Some(&write_qualitative),
        },
        &mut |e| {
            // between steps every finished scene is on disk: a front end
            // may end the process here, or stop the study after the scene
            // (rerun with resume to go on)
            observer.stop_point();
            match e {
                Event::SceneStart { .. } | Event::CalibrationStage { .. } => {}
                Event::Step { .. } => {
                    done += 1;
                    observer.progress(done);
                }
                Event::Skipped { name } => {
                    done += steps_per_scene;
                    observer.progress(done);
                    observer.say(&format!("  {name:<28} (result from an earlier run)"));
                }
                Event::Recomputed { name, reason } => {
                    observer.say(&format!("  {name:<28} recomputed: {reason}"));
                }
                Event::SceneDone { result } => observer.say(&scene_line(result)),
            }
            observer.checkpoint()
        },
    )?;
    observer.progress_finished();
    Ok(results)
}

/// Every scene's result from the shard that holds it, checked to be this
/// study's on exactly these inputs.
fn read_shards(
    plan: &EvalPlan,
    count: usize,
    observer: &mut dyn JobObserver,
) -> anyhow::Result<Vec<SceneResult>> {
    observer.progress_started("reading the shards", plan.scenes.len() as u64);
    let mut results = Vec::with_capacity(plan.scenes.len());
    for (i, source) in plan.scenes.iter().enumerate() {
        observer.checkpoint()?;
        let shard = Shard::of_scene(i, count);
        let name = source.name();
        let path = scene_path(&shard.folder(&plan.out), &name);
        let scene = source.load().with_context(|| format!("scene {name}"))?;
        let result =
            stored_result(&path, &scene, &plan.mask, &plan.study, i as u64).with_context(|| {
                format!(
                    "--merge {count}: scene {name} of shard {shard} (run `--shard {shard}` \
                     with the same flags first)"
                )
            })?;
        results.push(result);
        observer.progress(i as u64 + 1);
    }
    observer.progress_finished();
    Ok(results)
}

/// The shards' scene records and first-scene figures into the study's own
/// folders (inside the staging begun by the caller).
fn copy_shards(plan: &EvalPlan, count: usize, results: &[SceneResult]) -> anyhow::Result<()> {
    for (i, result) in results.iter().enumerate() {
        let from = scene_path(&Shard::of_scene(i, count).folder(&plan.out), &result.scene);
        let bytes =
            std::fs::read(&from).with_context(|| format!("cannot read {}", from.display()))?;
        cassi_io::write_atomic(scene_path(&plan.out, &result.scene), &bytes)?;
    }
    let figures = Shard::of_scene(0, count).folder(&plan.out).join("figures");
    if figures.is_dir() {
        copy_tree(&figures, &plan.out.join("figures"))?;
    }
    Ok(())
}

/// The summary, tables, report and figures of `results`, written inside
/// `staging` and committed together.
fn write_report(
    plan: &EvalPlan,
    results: Vec<SceneResult>,
    sweeps: Sweeps,
    staging: Staging,
    observer: &mut dyn JobObserver,
) -> anyhow::Result<EvalOutcome> {
    let summary = summarize(&results);
    write_all(
        &plan.out,
        &Setup {
            scenes: &plan.scenes_label,
            mask: &plan.mask_label,
        },
        &plan.study,
        &results,
        &summary,
        &sweeps,
    )?;
    observer.checkpoint()?;
    staging.commit()?;
    Ok(EvalOutcome {
        results,
        summary,
        sweeps,
    })
}

/// A finished scene in one line: calibration time and the first method's
/// PSNR in every scenario.
fn scene_line(result: &SceneResult) -> String {
    let first = &result.outcomes[0].method;
    let psnr: Vec<String> = result
        .outcomes
        .iter()
        .filter(|o| o.method == *first)
        .map(|o| format!("{:.2}", o.metrics.psnr))
        .collect();
    format!(
        "  {:<28} calibrated in {:.1} s; {first} PSNR I/I+n/II/III/IV {} dB",
        result.scene,
        result.calibration.seconds,
        psnr.join(" / ")
    )
}

/// The sensitivity curves (one per sweep preset) and the ablation the plan
/// asks for.
fn run_sweeps(plan: &EvalPlan, observer: &mut dyn JobObserver) -> anyhow::Result<Sweeps> {
    let mut sweeps = Sweeps::default();
    if !plan.sensitivity.is_empty() {
        for preset in &plan.sweep_presets {
            let base = Study {
                preset: preset.clone(),
                ..plan.study.clone()
            };
            let total = (plan.sensitivity.len() * plan.scenes.len()) as u64;
            observer.progress_started(&format!("sensitivity ({})", preset.name()), total);
            let mut done = 0;
            let points = sensitivity(
                &base,
                &plan.sensitivity,
                &plan.scenes,
                &plan.mask,
                &plan.out,
                plan.resume,
                &mut |scale, e| {
                    observer.stop_point();
                    if matches!(e, Event::SceneDone { .. } | Event::Skipped { .. }) {
                        done += 1;
                        observer.progress(done);
                    }
                    if let Event::Recomputed { name, reason } = &e {
                        observer.say(&format!("  {scale}×: {name:<24} recomputed: {reason}"));
                    }
                    if let Event::SceneDone { result } = e {
                        observer.say(&format!(
                            "  {scale}×: {:<24} errors {}",
                            result.scene,
                            result.errors.format_all()
                        ));
                    }
                },
            )?;
            observer.progress_finished();
            sweeps.sensitivity.push((preset.name().to_string(), points));
        }
    }
    if plan.ablation {
        let total = (plan.sweep_presets.len() * plan.scenes.len()) as u64;
        observer.progress_started("ablation", total);
        let mut done = 0;
        sweeps.ablation = Some(ablation(
            &plan.study,
            &plan.sweep_presets,
            &plan.scenes,
            &plan.mask,
            &mut |p| {
                observer.stop_point();
                if let SceneProgress::Step(_) = p {
                    observer.progress(done);
                    done += 1;
                }
            },
        )?);
        observer.progress_finished();
    }
    Ok(sweeps)
}
