//! `cassi.evaluate`: the four-scenario study of `cassi eval` from Python —
//! the whole study, one shard of it, or the merge of finished shards — so a
//! study spreads over processes or machines with whatever engine runs the
//! calls (Dask, Ray, a Slurm array).

use std::collections::HashMap;
use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use cassi_core::calib::Preset;
use cassi_core::optics::NoiseModel;
use cassi_core::recon::{Method, MethodId};
use cassi_eval::jobs::JobObserver;
use cassi_eval::jobs::eval::{
    EvalMode, EvalPlan, SceneSet, declare_outputs, mask_from_file, random_study_mask, run_eval,
};
use cassi_eval::learned::check_stride;
use cassi_eval::method::{LearnedMethod, StudyMethod};
use cassi_eval::protocol::Study;
use cassi_eval::shard::Shard;
use cassi_eval::study::SceneSource;
use cassi_eval::weights::resolve_weights;
use cassi_io::OutputSet;

use crate::errors::{Failure, compute, type_error, value_error};
use crate::learned;
use crate::params;

/// The shard from `"K/N"` or `(K, N)`.
fn shard_of(py: Python<'_>, obj: &Bound<'_, PyAny>) -> PyResult<Shard> {
    if let Ok(text) = obj.extract::<String>() {
        return Shard::parse(&text).map_err(|e| value_error(py, format!("shard {e}")));
    }
    if let Ok(t) = obj.cast::<PyTuple>()
        && let Ok((k, n)) = t.extract::<(usize, usize)>()
    {
        return Shard::new(k, n).map_err(|e| value_error(py, e.to_string()));
    }
    Err(type_error(
        py,
        format!("shard must be \"K/N\" or a tuple (K, N), got {obj:?}"),
    ))
}

/// The progress callback and Ctrl-C, seen from inside the GIL-free study.
struct PyObserver {
    progress: Option<Py<PyAny>>,
    label: String,
    total: u64,
    /// A Python exception (KeyboardInterrupt, or one the callback raised)
    /// that ends the study at its next checkpoint.
    pending: Option<PyErr>,
}

impl PyObserver {
    fn poll(&mut self, done: Option<u64>) {
        if self.pending.is_some() {
            return;
        }
        let result = Python::attach(|py| -> PyResult<()> {
            py.check_signals()?;
            if let (Some(cb), Some(done)) = (&self.progress, done) {
                let d = PyDict::new(py);
                d.set_item("stage", &self.label)?;
                d.set_item("done", done)?;
                d.set_item("total", self.total)?;
                cb.call1(py, (d,))?;
            }
            Ok(())
        });
        self.pending = result.err();
    }
}

impl JobObserver for PyObserver {
    fn progress_started(&mut self, label: &str, total: u64) {
        self.label = label.to_string();
        self.total = total;
        self.poll(Some(0));
    }
    fn progress(&mut self, done: u64) {
        self.poll(Some(done));
    }
    fn checkpoint(&mut self) -> anyhow::Result<()> {
        self.poll(None);
        match self.pending {
            Some(_) => anyhow::bail!("stopped from Python"),
            None => Ok(()),
        }
    }
    fn stop_point(&mut self) {
        self.poll(None);
    }
}

/// Runs the four-scenario study of `cassi eval` into the folder `out` and
/// returns its summary (the content of `summary.json`'s summary: mean
/// metrics per method and scenario, recovery ratios, parameter RMSE,
/// timings).
///
/// Scenes: `scenes` (a folder of cubes, .npy/.npz/.mat, values in [0, 1])
/// or `synthetic` (that many embedded scenes of `size`×`size`×28, seeds
/// 0, 1, …); `limit` keeps the first few. `mask`: a mask file (`mask_var`
/// inside it), or None for a random binary `size`×`size` mask (synthetic
/// scenes only). `methods`: iterative solvers (`cassi.ITERATIVE_METHODS`)
/// and, with the networks built (`cassi.NETS_BUILT`), learned ones with
/// their `weights` ({method: file}) or a `weights_dir` searched as the CLI
/// does; `iterations` overrides the iterative counts. The true instrument: `mismatch`
/// (default "paper"; a dict of `cassi.PARAMETERS` keys, or keywords
/// `**params`), dispersion `model` ("rounded" or "subpixel"), nominal
/// `stride`; detector noise as `cassi.simulate` takes it. `preset`: the
/// calibration preset (`cassi.PRESETS`).
///
/// Scale-out: `shard=(K, N)` (or "K/N") runs only scenes K, K + N, … into
/// `out/shards/K-of-N/` and returns that shard's summary; once all N have
/// finished, `merge=N` with the same arguments checks every scene record
/// and writes the report one process would have written (same scores,
/// timings aside). `resume=True` reuses finished scenes of the same study.
/// `progress`, if given, is called with {stage, done, total}. Ctrl-C stops
/// the study once the scene in progress is written (finished scenes stay
/// for `resume`).
#[pyfunction]
#[pyo3(signature = (out, *, scenes=None, synthetic=None, size=256, limit=None, mask=None, mask_var=None, methods=vec!["gap-tv".to_string()], weights=None, weights_dir=None, iterations=None, preset="default", mismatch=None, model="rounded", stride=2.0, noise=true, photon_peak=Some(1e5), read_noise=0.01, seed=0, resume=false, shard=None, merge=None, progress=None, **params))]
#[allow(clippy::too_many_arguments)]
pub fn evaluate<'py>(
    py: Python<'py>,
    out: PathBuf,
    scenes: Option<PathBuf>,
    synthetic: Option<usize>,
    size: usize,
    limit: Option<usize>,
    mask: Option<PathBuf>,
    mask_var: Option<String>,
    methods: Vec<String>,
    weights: Option<HashMap<String, PathBuf>>,
    weights_dir: Option<PathBuf>,
    iterations: Option<usize>,
    preset: &str,
    mismatch: Option<&Bound<'py, PyAny>>,
    model: &str,
    stride: f64,
    noise: bool,
    photon_peak: Option<f64>,
    read_noise: f64,
    seed: u64,
    resume: bool,
    shard: Option<&Bound<'py, PyAny>>,
    merge: Option<usize>,
    progress: Option<Bound<'py, PyAny>>,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let scene_set = match (&scenes, synthetic) {
        (Some(_), None) if mask.is_none() => {
            return Err(value_error(
                py,
                "scenes from a folder need their nominal mask (mask=...)",
            ));
        }
        (Some(dir), None) => SceneSet::folder(dir).map_err(Failure::Study)?,
        (None, Some(0)) => return Err(value_error(py, "synthetic=0: a study needs a scene")),
        (None, Some(n)) => SceneSet::synthetic(n, size),
        _ => {
            return Err(value_error(
                py,
                "give exactly one of scenes (a folder) and synthetic (a count)",
            ));
        }
    };
    let mode = match (shard, merge) {
        (Some(_), Some(_)) => return Err(value_error(py, "give shard or merge, not both")),
        (Some(s), None) => EvalMode::Shard(shard_of(py, s)?),
        (None, Some(n)) => EvalMode::Merge { count: n },
        (None, None) => EvalMode::Whole,
    };
    let mismatch = match mismatch {
        None => {
            let paper = pyo3::types::PyString::new(py, "paper").into_any();
            params::mismatch(py, stride, Some(&paper), params)?
        }
        Some(m) => params::mismatch(py, stride, Some(m), params)?,
    };
    let instrument = params::model(py, model)?;
    let noise = match noise {
        true => NoiseModel {
            photon_peak,
            read_noise,
            seed,
        },
        false => NoiseModel {
            photon_peak: None,
            read_noise: 0.0,
            seed: 0,
        },
    };
    noise
        .validate()
        .map_err(|e| value_error(py, e.to_string()))?;
    // learned methods' weights by method name, checked against the registry
    let mut given = Vec::new();
    for (name, path) in weights.unwrap_or_default() {
        let id = MethodId::parse(&name).map_err(|e| value_error(py, format!("weights: {e}")))?;
        given.push((id, path));
    }
    let mut study_methods: Vec<StudyMethod> = Vec::new();
    for name in &methods {
        let id = MethodId::parse(name).map_err(|e| value_error(py, e.to_string()))?;
        match Method::defaults(id) {
            Some(method) => study_methods.push(method.with_overrides(iterations, None).into()),
            None => {
                learned::require_nets(py, id)?;
                let file = resolve_weights(id, &given, weights_dir.as_deref())
                    .map_err(|e| value_error(py, format!("{e:#}")))?;
                check_stride(id, stride).map_err(|e| value_error(py, format!("{e:#}")))?;
                let iterations = iterations.filter(|_| id.kind().has_iterations());
                let loaded = py
                    .detach(|| LearnedMethod::new(id, file, iterations).load())
                    .map_err(|e| value_error(py, format!("{e:#}")))?;
                study_methods.push(StudyMethod::Learned(loaded));
            }
        }
    }
    let preset = Preset::by_name(preset, stride).map_err(|e| value_error(py, e.to_string()))?;
    let progress = progress.map(Bound::unbind);
    let mut observer = PyObserver {
        progress,
        label: String::new(),
        total: 0,
        pending: None,
    };
    let result = compute(py, || {
        let run = || -> anyhow::Result<_> {
            // every file read and written, compared before any work; every
            // listed scene is protected, read or not (limit)
            let mut set = OutputSet::new();
            for scene in &scene_set.scenes {
                if let SceneSource::File { path } = scene {
                    set.input("a scene of scenes", path);
                }
            }
            let SceneSet {
                scenes,
                label: scenes_label,
            } = scene_set.limit(limit);
            if let Some(p) = &mask {
                set.input("mask", p);
            }
            declare_outputs(&mut set, &out, false, mode);
            let checked = set.check()?;
            let (mask, mask_label) = match &mask {
                Some(p) => mask_from_file(p, mask_var.as_deref())?,
                None => random_study_mask(size)?,
            };
            let plan = EvalPlan {
                study: Study {
                    mismatch,
                    instrument,
                    noise,
                    preset,
                    methods: study_methods,
                    stride,
                },
                scenes,
                mask,
                scenes_label,
                mask_label,
                out: out.clone(),
                resume,
                sensitivity: Vec::new(),
                ablation: false,
                sweep_presets: Vec::new(),
                mode,
            };
            plan.check()?;
            let outcome = run_eval(&plan, checked, &mut observer)?;
            Ok(serde_json::to_string(&outcome.summary)?)
        };
        run().map_err(Failure::Study)
    });
    if let Some(e) = observer.pending {
        return Err(e);
    }
    let json = result?;
    py.import("json")?.call_method1("loads", (json,))
}
