//! A study over many scenes, safe to interrupt: each scene's result is
//! written (atomically, a [`SceneRecord`]) as it finishes, with SHA-256
//! digests of its inputs (the scene's data, the mask's data, every setting), to
//! `<out>/.pending/scenes/<name>.json` — beside, not over, the results of the
//! last finished study in `<out>/scenes/`. [`promote_pending`] moves a
//! finished run's files into place (inside the caller's output set, so they
//! land together with the report). A resumed run reuses a result, pending or
//! promoted, only when it is a current record and all three digests match
//! exactly; otherwise it recomputes the scene and says why.

use std::path::{Path, PathBuf};

use anyhow::Context;
use cassi_core::synth::{SceneSpec, synthetic_scene};
use cassi_core::{Cube, Mask};
use serde::{Deserialize, Serialize};

use crate::digests::InputDigests;
use crate::protocol::{Reconstructions, SceneProgress, SceneResult, Study, run_scene};
use crate::records::{Record, SceneRecord, read_versioned, write_record};
use crate::shard::Shard;

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
    /// A self-calibration stage inside the current scene ended (not a
    /// counted step: only a point where the work may stop).
    CalibrationStage { name: &'a str },
    /// A scene's result was found from an earlier run with the same inputs.
    Skipped { name: &'a str },
    /// A resumed run found an earlier result for this scene but recomputes
    /// it: `reason` says which input differs.
    Recomputed { name: &'a str, reason: String },
    /// A scene finished and its result is on disk.
    SceneDone { result: &'a SceneResult },
}

/// Where a finished study keeps a scene's result.
pub fn scene_path(out: &Path, name: &str) -> PathBuf {
    out.join("scenes").join(format!("{name}.json"))
}

/// The folder inside `out` where a running study keeps what it has finished
/// until [`promote_pending`] moves it into place.
pub const PENDING: &str = ".pending";

/// Moves every file a study left in `<out>/.pending/` (and in the pending
/// folders of the sweeps under `out`) to the same place under `out`, through
/// [`cassi_io::write_atomic`] — so inside an output set's staging they are
/// committed together with the rest — and returns the pending folders to
/// remove once that commit succeeded ([`remove_pending`]).
pub fn promote_pending(out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut folders = Vec::new();
    collect_pending(out, &mut folders)?;
    for pending in &folders {
        let target = pending.parent().unwrap_or(out);
        copy_tree(pending, target)?;
    }
    Ok(folders)
}

/// Removes promoted pending folders (after their files were committed).
pub fn remove_pending(folders: &[PathBuf]) -> anyhow::Result<()> {
    for f in folders {
        std::fs::remove_dir_all(f).with_context(|| format!("cannot remove {}", f.display()))?;
    }
    Ok(())
}

fn collect_pending(dir: &Path, found: &mut Vec<PathBuf>) -> anyhow::Result<()> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if !entry.file_type().is_ok_and(|t| t.is_dir()) {
            continue;
        }
        if entry.file_name() == PENDING {
            found.push(path);
        } else {
            collect_pending(&path, found)?;
        }
    }
    Ok(())
}

/// Copies the files under `from` to the same places under `to` through
/// [`cassi_io::write_atomic`] (so inside an output set's staging they are
/// committed with the rest); hidden files (temporaries) are left out.
pub fn copy_tree(from: &Path, to: &Path) -> anyhow::Result<()> {
    for entry in
        std::fs::read_dir(from).with_context(|| format!("cannot list {}", from.display()))?
    {
        let entry = entry?;
        let (src, dst) = (entry.path(), to.join(entry.file_name()));
        if entry.file_type()?.is_dir() {
            // a sweep's study folder nests below the declared output folder
            std::fs::create_dir_all(&dst)
                .with_context(|| format!("cannot create {}", dst.display()))?;
            copy_tree(&src, &dst)?;
        } else if !entry.file_name().to_string_lossy().starts_with('.') {
            // (hidden files are temporaries of an interrupted write)
            let bytes =
                std::fs::read(&src).with_context(|| format!("cannot read {}", src.display()))?;
            cassi_io::write_atomic(&dst, &bytes)?;
        }
    }
    Ok(())
}

/// Draws the first scene's qualitative figures into a study folder: (folder,
/// scene name, method name, true scene, reconstructions). The runner calls
/// it and the presentation layer supplies it, so the runner draws nothing.
pub type QualitativeFigures<'a> =
    &'a dyn Fn(&Path, &str, &str, &Cube, &Reconstructions) -> anyhow::Result<()>;

/// How a study runs: whether it reuses earlier results, which share of the
/// scenes it runs, and who draws the first scene's qualitative figures.
#[derive(Clone, Copy, Default)]
pub struct RunOptions<'a> {
    /// Load scenes whose file holds a result of the same study instead of
    /// rerunning them.
    pub resume: bool,
    /// Run only this shard's scenes (each keeps its index and noise seed).
    pub shard: Option<Shard>,
    /// Draws the first scene's panel and spectra (when this run holds it).
    pub qualitative: Option<QualitativeFigures<'a>>,
}

/// Runs `study` on every scene (scene i uses noise seed i) or on one shard's
/// share of them, writing each result to `<out>/scenes/`. `on_event` hears
/// every event; an error it returns ends the study there (finished scenes
/// stay on disk for a resumed run; a step's error ends it once that scene
/// is written).
pub fn run_study(
    study: &Study,
    scenes: &[SceneSource],
    mask: &Mask,
    out: &Path,
    options: RunOptions<'_>,
    on_event: &mut dyn FnMut(Event<'_>) -> anyhow::Result<()>,
) -> anyhow::Result<Vec<SceneResult>> {
    let RunOptions {
        resume,
        shard,
        qualitative,
    } = options;
    let held = |i: usize| shard.is_none_or(|s| s.holds(i));
    let pending = out.join(PENDING);
    if !resume && pending.exists() {
        // an interrupted run's work is kept only for --resume
        std::fs::remove_dir_all(&pending)
            .with_context(|| format!("cannot clear {}", pending.display()))?;
    }
    std::fs::create_dir_all(pending.join("scenes"))
        .with_context(|| format!("cannot create {}", pending.join("scenes").display()))?;
    let mut results = Vec::with_capacity(scenes.len());
    for (i, source) in scenes.iter().enumerate().filter(|&(i, _)| held(i)) {
        let name = source.name();
        let path = scene_path(&pending, &name);
        let noise_seed = i as u64;
        let scene = source.load().with_context(|| format!("scene {name}"))?;
        let inputs = InputDigests::new(&scene, mask, study, noise_seed)?;
        if resume {
            // this run's own earlier (interrupted) work first, then the last
            // finished study's
            let earlier = match earlier_result(&path, &inputs) {
                Earlier::None => earlier_result(&scene_path(out, &name), &inputs),
                e => e,
            };
            match earlier {
                Earlier::Same(r) => {
                    on_event(Event::Skipped { name: &name })?;
                    results.push(*r);
                    continue;
                }
                Earlier::Different(reason) => on_event(Event::Recomputed {
                    name: &name,
                    reason,
                })?,
                Earlier::None => {}
            }
        }
        on_event(Event::SceneStart {
            index: i,
            count: scenes.len(),
            name: &name,
        })?;
        // the first scene also gets the qualitative figures
        let keep = qualitative.is_some() && i == 0;
        // a step's callback cannot return: its first error is kept for
        // after the scene
        let mut stopped = None;
        let (result, kept) = run_scene(&name, &scene, mask, study, noise_seed, keep, &mut |p| {
            if stopped.is_none() {
                stopped = on_event(match p {
                    SceneProgress::Step(name) => Event::Step { name },
                    SceneProgress::CalibrationStage(name) => Event::CalibrationStage { name },
                })
                .err();
            }
        })
        .with_context(|| format!("scene {name}"))?;
        if let (Some(method), Some(draw)) = (study.methods.first().filter(|_| keep), qualitative) {
            draw(&pending, &name, method.name(), &scene, &kept)
                .with_context(|| format!("qualitative figures of scene {name}"))?;
        }
        let record = SceneRecord {
            study: study.clone(),
            noise_seed,
            inputs: Some(inputs),
            result,
        };
        write_record(&path, &record)?;
        if let Some(e) = stopped {
            return Err(e);
        }
        on_event(Event::SceneDone {
            result: &record.result,
        })?;
        results.push(record.result);
    }
    // pending records of scenes this run does not hold (an earlier,
    // interrupted run over other scenes) must not be promoted with it
    let names: Vec<String> = scenes
        .iter()
        .enumerate()
        .filter(|&(i, _)| held(i))
        .map(|(_, s)| format!("{}.json", s.name()))
        .collect();
    for entry in std::fs::read_dir(pending.join("scenes"))?.flatten() {
        if !names
            .iter()
            .any(|n| *n == *entry.file_name().to_string_lossy())
        {
            let _ = std::fs::remove_file(entry.path());
        }
    }
    Ok(results)
}

/// The result a finished run left at `path` for `scene` (noise seed
/// `noise_seed`), checked to be a current record of `study` made from
/// exactly these inputs; an error naming the file says what is missing or
/// differs.
pub fn stored_result(
    path: &Path,
    scene: &Cube,
    mask: &Mask,
    study: &Study,
    noise_seed: u64,
) -> anyhow::Result<SceneResult> {
    let inputs = InputDigests::new(scene, mask, study, noise_seed)?;
    match earlier_result(path, &inputs) {
        Earlier::Same(r) => Ok(*r),
        Earlier::None => anyhow::bail!("{}: no such result", path.display()),
        Earlier::Different(reason) => anyhow::bail!("{}: {reason}", path.display()),
    }
}

/// What an earlier run left for a scene.
enum Earlier {
    /// Nothing (no file): the scene simply runs.
    None,
    /// A result made from exactly these inputs.
    Same(Box<SceneResult>),
    /// A file that cannot be reused, and why.
    Different(String),
}

/// The earlier result at `path`, reusable only when it is a current record
/// and its input digests equal `inputs`.
fn earlier_result(path: &Path, inputs: &InputDigests) -> Earlier {
    let earlier = match read_versioned::<SceneRecord>(path) {
        Ok(e) => e,
        Err(e) if e.is_missing() => return Earlier::None,
        Err(e) => return Earlier::Different(format!("the earlier result is unreadable ({e})")),
    };
    if earlier.version < SceneRecord::VERSION {
        return Earlier::Different(format!(
            "the earlier result is a version-{} record (written by an older cassi)",
            earlier.version
        ));
    }
    match earlier.record.inputs {
        None => Earlier::Different(
            "the earlier result has no input digests (written by an older cassi)".into(),
        ),
        Some(digests) => match inputs.difference(&digests) {
            None => Earlier::Same(Box::new(earlier.record.result)),
            Some(reason) => Earlier::Different(reason),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::StudyMethod;
    use cassi_core::Mismatch;
    use cassi_core::calib::Preset;
    use cassi_core::optics::{DispersionModel, NoiseModel};
    use cassi_core::recon::Method;

    fn study() -> Study {
        Study {
            mismatch: Mismatch::paper(),
            instrument: DispersionModel::Rounded,
            noise: NoiseModel::default(),
            preset: Preset::by_name("default", 2.0).unwrap(),
            methods: vec![StudyMethod::from(Method::by_name("gap-tv").unwrap())],
            stride: 2.0,
        }
    }

    #[test]
    fn digests_tell_which_input_changed() {
        let scene = Cube::from_vec(2, 3, 4, (0..24).map(|v| v as f32 / 24.0).collect()).unwrap();
        let mask = Mask::from_vec(
            3,
            4,
            vec![1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0],
        )
        .unwrap();
        let base = InputDigests::new(&scene, &mask, &study(), 0).unwrap();
        assert_eq!(base, InputDigests::new(&scene, &mask, &study(), 0).unwrap());
        assert_eq!(base.difference(&base), None);

        let mut other_mask = mask.clone();
        other_mask.as_mut_slice()[5] = 0.5;
        let d = InputDigests::new(&scene, &other_mask, &study(), 0).unwrap();
        assert_eq!(
            d.difference(&base).unwrap(),
            "the mask's data differ from the earlier run's"
        );

        // same values, another shape: a different scene
        let reshaped = Cube::from_vec(2, 4, 3, scene.as_slice().to_vec()).unwrap();
        let d = InputDigests::new(&reshaped, &mask, &study(), 0).unwrap();
        assert!(d.difference(&base).unwrap().starts_with("the scene's data"));

        let d = InputDigests::new(&scene, &mask, &study(), 1).unwrap();
        assert!(d.difference(&base).unwrap().starts_with("the settings"));
        let mut s = study();
        s.mismatch.dx = 1.25;
        let d = InputDigests::new(&scene, &mask, &s, 0).unwrap();
        assert!(d.difference(&base).unwrap().starts_with("the settings"));
    }

    fn reason(e: Earlier) -> String {
        match e {
            Earlier::Different(reason) => reason,
            Earlier::Same(_) => panic!("reused"),
            Earlier::None => panic!("not found"),
        }
    }

    /// `--resume` reuses only a current record made from the same inputs;
    /// an old-version (headerless) or newer record is recomputed, with why.
    #[test]
    fn resume_reuses_only_current_records_of_the_same_inputs() {
        let dir = std::env::temp_dir().join(format!("cassi-study-earlier-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // written by cassi before records had a header
        let old = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/v0/scene.json");
        let record = read_versioned::<SceneRecord>(&old).unwrap().record;
        let inputs = record.inputs.clone().unwrap();
        assert!(reason(earlier_result(&old, &inputs)).contains("version-0 record"));

        let current = dir.join("scene.json");
        write_record(&current, &record).unwrap();
        assert!(matches!(
            earlier_result(&current, &inputs),
            Earlier::Same(_)
        ));
        let mut other = inputs.clone();
        other.mask = "0".repeat(64);
        assert!(reason(earlier_result(&current, &other)).starts_with("the mask's data"));
        assert!(matches!(
            earlier_result(&dir.join("absent.json"), &inputs),
            Earlier::None
        ));

        let text = std::fs::read_to_string(&current).unwrap();
        let newer = dir.join("newer.json");
        std::fs::write(&newer, text.replacen("\"version\": 1", "\"version\": 2", 1)).unwrap();
        let why = reason(earlier_result(&newer, &inputs));
        assert!(
            why.contains("newer.json") && why.contains("newer cassi"),
            "{why}"
        );
    }
}
