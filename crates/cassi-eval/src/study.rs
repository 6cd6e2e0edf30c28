//! A study over many scenes, safe to interrupt: each scene's result is
//! written (atomically) as it finishes, to `<out>/scenes/<name>.json`, and a
//! resumed run skips the scenes whose result exists and was made with the
//! same study settings.

use std::path::{Path, PathBuf};

use anyhow::Context;
use cassi_core::synth::{SceneSpec, synthetic_scene};
use cassi_core::{Cube, Mask};
use serde::{Deserialize, Serialize};

use crate::protocol::{SceneResult, Study, run_scene};

/// Where a scene comes from.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum SceneSource {
    /// A cube file (.npy, .npz, .mat), values in [0, 1].
    File { path: PathBuf },
    /// The embedded procedural scene.
    Synthetic {
        seed: u64,
        rows: usize,
        cols: usize,
        wavelengths_nm: Vec<f64>,
    },
}

impl SceneSource {
    /// The name results are filed under.
    pub fn name(&self) -> String {
        match self {
            Self::File { path } => path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| path.display().to_string()),
            Self::Synthetic { seed, .. } => format!("synthetic_{seed}"),
        }
    }

    pub fn load(&self) -> anyhow::Result<Cube> {
        match self {
            Self::File { path } => Ok(cassi_io::load_cube(path, None, cassi_io::CubeLayout::Auto)?),
            Self::Synthetic {
                seed,
                rows,
                cols,
                wavelengths_nm,
            } => Ok(synthetic_scene(&SceneSpec {
                rows: *rows,
                cols: *cols,
                wavelengths_nm: wavelengths_nm.clone(),
                seed: *seed,
            })?),
        }
    }
}

/// Every `.npy`, `.npz` and `.mat` file of `dir`, sorted by name.
pub fn scenes_in(dir: &Path) -> anyhow::Result<Vec<SceneSource>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot list the scene folder {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .is_some_and(|e| e == "npy" || e == "npz" || e == "mat")
        })
        .collect();
    paths.sort();
    if paths.is_empty() {
        anyhow::bail!("{}: no scene files (.npy, .npz, .mat) found", dir.display());
    }
    Ok(paths
        .into_iter()
        .map(|path| SceneSource::File { path })
        .collect())
}

/// What a study run reports as it goes.
pub enum Event<'a> {
    /// A scene starts (`index` of `count`).
    SceneStart {
        index: usize,
        count: usize,
        name: &'a str,
    },
    /// A step inside the current scene.
    Step { name: &'a str },
    /// A scene's result was found from an earlier run.
    Skipped { name: &'a str },
    /// A scene finished and its result is on disk.
    SceneDone { result: &'a SceneResult },
}

/// A scene's result file as written: the study it belongs to, then the result.
#[derive(Serialize, Deserialize)]
struct Record {
    study: Study,
    noise_seed: u64,
    result: SceneResult,
}

pub fn scene_path(out: &Path, name: &str) -> PathBuf {
    out.join("scenes").join(format!("{name}.json"))
}

/// Runs `study` on every scene (scene i uses noise seed i), writing each
/// result to `<out>/scenes/` (and, with `qualitative`, the first scene's
/// panel and spectra to `<out>/figures/`). With `resume`, scenes whose file holds a
/// result of the same study are loaded, not rerun.
pub fn run_study(
    study: &Study,
    scenes: &[SceneSource],
    mask: &Mask,
    out: &Path,
    resume: bool,
    qualitative: bool,
    on_event: &mut dyn FnMut(Event<'_>),
) -> anyhow::Result<Vec<SceneResult>> {
    std::fs::create_dir_all(out.join("scenes"))
        .with_context(|| format!("cannot create {}", out.join("scenes").display()))?;
    let mut results = Vec::with_capacity(scenes.len());
    for (i, source) in scenes.iter().enumerate() {
        let name = source.name();
        let path = scene_path(out, &name);
        let noise_seed = i as u64;
        if resume && let Some(r) = load_matching(&path, study, noise_seed) {
            on_event(Event::Skipped { name: &name });
            results.push(r);
            continue;
        }
        on_event(Event::SceneStart {
            index: i,
            count: scenes.len(),
            name: &name,
        });
        let scene = source.load().with_context(|| format!("scene {name}"))?;
        // the first scene also gets the qualitative figures
        let keep = qualitative && i == 0;
        let (result, kept) = run_scene(&name, &scene, mask, study, noise_seed, keep, &mut |step| {
            on_event(Event::Step { name: step })
        })
        .with_context(|| format!("scene {name}"))?;
        if let Some(method) = study.methods.first().filter(|_| keep) {
            crate::study_figures::write_qualitative(out, &name, method.name(), &scene, &kept)
                .with_context(|| format!("qualitative figures of scene {name}"))?;
        }
        let record = Record {
            study: study.clone(),
            noise_seed,
            result,
        };
        let text = serde_json::to_string_pretty(&record)? + "\n";
        cassi_io::write_atomic(&path, text.as_bytes())?;
        on_event(Event::SceneDone {
            result: &record.result,
        });
        results.push(record.result);
    }
    Ok(results)
}

/// The result in `path` if it exists, parses and was made by `study`.
fn load_matching(path: &Path, study: &Study, noise_seed: u64) -> Option<SceneResult> {
    let text = std::fs::read_to_string(path).ok()?;
    let record: Record = serde_json::from_str(&text).ok()?;
    // compare through JSON: f64 fields round-trip exactly
    let same = serde_json::to_value(&record.study).ok()? == serde_json::to_value(study).ok()?;
    (same && record.noise_seed == noise_seed).then_some(record.result)
}
