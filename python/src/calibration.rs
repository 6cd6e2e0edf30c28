//! `cassi.calibrate` and its result, `cassi.Calibration`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::time::Duration;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use cassi_core::Parameter;
use cassi_core::calib::{self, CalibrationProblem, Preset, StageReport, Uncertainty};
use cassi_core::optics::{MaskCode, mask_code, validate_measurement};

use crate::arrays;
use crate::errors::{Failure, catch, value_error};
use crate::params;

/// The result of a self-calibration: the estimated mismatch, its standard
/// errors, the parameter pairs the data pin only in combination, and what
/// each stage did. Pass it to `reconstruct(..., calibration=cal)` or to
/// `Operator(mask, mismatch=cal, model=cal.model)`.
#[pyclass(name = "Calibration", module = "cassi", frozen)]
pub struct PyCalibration {
    pub inner: calib::Calibration,
}

fn stage_dict<'py>(py: Python<'py>, s: &StageReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("name", &s.name)?;
    d.set_item("evaluations", s.evaluations)?;
    d.set_item("seconds", s.seconds)?;
    d.set_item("parameters", params::to_dict(py, &s.parameters)?)?;
    d.set_item("score", s.score)?;
    // a choosing stage's other answer (the held curvature's restart), else None
    let passed_over = match &s.passed_over {
        Some(other) => {
            let o = PyDict::new(py);
            o.set_item("parameters", params::to_dict(py, &other.parameters)?)?;
            o.set_item("score", other.score)?;
            Some(o)
        }
        None => None,
    };
    d.set_item("passed_over", passed_over)?;
    Ok(d)
}

#[pymethods]
impl PyCalibration {
    /// The preset that ran ("default" or "paper").
    #[getter]
    fn preset(&self) -> &str {
        &self.inner.preset
    }

    /// The dispersion model fitted ("rounded", "subpixel", "dispersed-mask" or "crisp-cells").
    #[getter]
    fn model(&self) -> &'static str {
        self.inner.model.name()
    }

    /// The estimated mismatch ψ: {dx, dy, theta_deg, a1, alpha_deg,
    /// blur_sigma_px} in pixels, degrees and pixels per band.
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        params::to_dict(py, &self.inner.parameters)
    }

    /// The parameters `reconstruct(..., calibration=cal)` uses: `parameters`
    /// themselves (since stop 63 the blur pass's σ too), or with
    /// blur_sigma_px the calibrated model's own fit where the calibration
    /// kept it to reconstruct with (the pass run as before stop 62 — the
    /// real snapshots — or settings that say so); where the answer lies on
    /// the pixel grid, blur_sigma_px plus the on-grid margin (0.03 px since
    /// stop 68: GAP-TV reconstructs better there with more blur).
    #[getter]
    fn reconstruction_parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        params::to_dict(py, &self.inner.reconstruction_parameters())
    }

    /// The standard error of each parameter (same keys and units), None
    /// where it was not estimated.
    #[getter]
    fn standard_errors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        per_parameter(py, &self.inner.uncertainty)
    }

    /// The half-width of each parameter's 95 % interval (same keys and
    /// units; not twice the standard error: the errors are heavy-tailed),
    /// None where it was not estimated (the `paper` preset, the rounded
    /// model).
    #[getter]
    fn intervals_95<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        per_parameter(py, &self.inner.interval_95)
    }

    /// Each parameter's 95 % interval as (low, high) (same keys and
    /// units): the estimate ∓ `intervals_95`, the low end raised to what
    /// the parameter can take — a blur's 0, so a σ the data do not resolve
    /// from 0 reads (0.0, high), bounded above only, as the repr prints
    /// it. None where no half-width was stated.
    #[getter]
    fn ranges_95<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in Parameter::ALL {
            d.set_item(p.key(), self.inner.range_95(p))?;
        }
        Ok(d)
    }

    /// Pairs of parameters whose errors are correlated by at least 0.8
    /// (the data pin their combination, not each): a list of
    /// (key_a, key_b, correlation).
    #[getter]
    fn trade_offs(&self) -> Vec<(&'static str, &'static str, f64)> {
        self.inner
            .trade_offs
            .iter()
            .map(|t| (t.a.key(), t.b.key(), t.correlation))
            .collect()
    }

    /// Each stage as {name, evaluations, seconds, parameters, score,
    /// passed_over}: passed_over is {parameters, score} of the answer a
    /// choosing stage did not keep (the held curvature's restart, the scene
    /// fit's nominal start), else None.
    #[getter]
    fn stages<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for s in &self.inner.stages {
            list.append(stage_dict(py, s)?)?;
        }
        Ok(list)
    }

    /// What the ridge probes found (`calibrate(..., ridge_probes=True)`),
    /// else None: {"ends": [{ridge ("dx_a1" or "dy_alpha"), moved ("first"
    /// or "last": the end band the profile moved), step_px,
    /// dip_relative_objective, parameters, distance_px,
    /// relative_objective, alternative}], "profiles": [{ridge, moved,
    /// steps_px, relative_objective}]}. An end with alternative True
    /// scored within the margin of the answer, half a pixel or more away:
    /// the data do not rule it out, and the errors reach it.
    #[getter]
    fn ridge_probes<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(report) = &self.inner.ridge_probes else {
            return Ok(None);
        };
        let key = |v: serde_json::Value| v.as_str().unwrap_or_default().to_string();
        let named = |ridge, moved| -> (String, String) {
            (key(serde_json::json!(ridge)), key(serde_json::json!(moved)))
        };
        let ends = PyList::empty(py);
        for e in &report.ends {
            let d = PyDict::new(py);
            let (ridge, moved) = named(e.ridge, e.moved);
            d.set_item("ridge", ridge)?;
            d.set_item("moved", moved)?;
            d.set_item("step_px", e.step_px)?;
            d.set_item("dip_relative_objective", e.dip_relative_objective)?;
            d.set_item("parameters", params::to_dict(py, &e.parameters)?)?;
            d.set_item("distance_px", e.distance_px)?;
            d.set_item("relative_objective", e.relative_objective)?;
            d.set_item("alternative", e.alternative)?;
            ends.append(d)?;
        }
        let profiles = PyList::empty(py);
        for p in &report.profiles {
            let d = PyDict::new(py);
            let (ridge, moved) = named(p.ridge, p.moved);
            d.set_item("ridge", ridge)?;
            d.set_item("moved", moved)?;
            d.set_item("steps_px", p.steps_px.clone())?;
            d.set_item("relative_objective", p.relative_objective.clone())?;
            profiles.append(d)?;
        }
        let d = PyDict::new(py);
        d.set_item("ends", ends)?;
        d.set_item("profiles", profiles)?;
        Ok(Some(d))
    }

    /// The bands' departures from the straight dispersion (px along it, one
    /// per band) the calibration held (`band_offsets=`), which a
    /// reconstruction with this calibration holds too; None without.
    #[getter]
    fn band_offsets(&self) -> Option<Vec<f64>> {
        self.inner.band_offsets.as_ref().map(|o| o.offsets.clone())
    }

    /// Where each band's light lies along the dispersion in the fitted
    /// model ("point", "uniform" or "linear"; `band_spread=`), which a
    /// reconstruction with this calibration spreads too.
    #[getter]
    fn band_spread(&self) -> &'static str {
        self.inner.band_spread.name()
    }

    /// Proxy score of the estimate (the final proxy).
    #[getter]
    fn score(&self) -> f64 {
        self.inner.score
    }

    /// Proxy score of the nominal parameters (the same proxy).
    #[getter]
    fn nominal_score(&self) -> f64 {
        self.inner.nominal_score
    }

    /// Wall-clock seconds of the whole calibration.
    #[getter]
    fn seconds(&self) -> f64 {
        self.inner.seconds
    }

    /// Score evaluations, all stages together.
    #[getter]
    fn evaluations(&self) -> usize {
        self.inner.evaluations
    }

    /// Where this calibration combines several snapshots
    /// (`combine_calibrations`): {"parameters": [each snapshot's dict],
    /// "consistency": [{parameter, chi_squared, dof, p_value, spread,
    /// disagree, farthest} per parameter], "joint_fit_from": the
    /// combination's parameters where the answer is the snapshots' joint
    /// fit, else None} (farthest: the index of the snapshot without which
    /// the others agree best, None for two); None for a single snapshot's.
    #[getter]
    fn snapshots<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(spread) = &self.inner.snapshots else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        let answers = spread
            .parameters
            .iter()
            .map(|m| params::to_dict(py, m))
            .collect::<PyResult<Vec<_>>>()?;
        d.set_item("parameters", answers)?;
        let consistency = PyList::empty(py);
        for c in &spread.consistency {
            let e = PyDict::new(py);
            e.set_item("parameter", c.parameter.key())?;
            e.set_item("chi_squared", c.chi_squared)?;
            e.set_item("dof", c.dof)?;
            e.set_item("p_value", c.p_value)?;
            e.set_item("spread", c.spread)?;
            e.set_item("disagree", c.disagree)?;
            e.set_item("farthest", c.farthest)?;
            consistency.append(e)?;
        }
        d.set_item("consistency", consistency)?;
        let joint_from = match &spread.joint_fit_from {
            Some(m) => Some(params::to_dict(py, m)?),
            None => None,
        };
        d.set_item("joint_fit_from", joint_from)?;
        Ok(Some(d))
    }

    /// The library's JSON form of the result (what `from_json` reads).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string_pretty(&self.inner)
            .map_err(|e| value_error_here(format!("serialising the calibration: {e}")))
    }

    /// A calibration from its JSON form (`to_json`, or the file `cassi
    /// calibrate -o calib.json` writes).
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        let inner: calib::Calibration = serde_json::from_str(text)
            .map_err(|e| value_error(py, format!("not a cassi calibration: {e}")))?;
        inner
            .parameters
            .validate()
            .map_err(|e| value_error(py, e.to_string()))?;
        Ok(Self { inner })
    }

    fn __repr__(&self) -> String {
        let mut out = format!(
            "Calibration(preset={:?}, model={:?}, {:.1} s, {} evaluations)\n  {}",
            self.inner.preset,
            self.inner.model.name(),
            self.inner.seconds,
            self.inner.evaluations,
            Parameter::format_all(&self.inner.parameters)
        );
        for line in Parameter::ALL
            .iter()
            .filter_map(|&p| self.inner.uncertainty_line(p))
        {
            out += &format!("\n  {line}");
        }
        out
    }
}

/// {key: value or None} over every parameter.
fn per_parameter<'py>(py: Python<'py>, u: &Uncertainty) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for p in Parameter::ALL {
        d.set_item(p.key(), u.get(p))?;
    }
    Ok(d)
}

fn value_error_here(msg: String) -> PyErr {
    Python::attach(|py| value_error(py, msg))
}

/// Several snapshots' calibrations of one instrument (the same mask,
/// stride, model and preset; different scenes) combined into one: each
/// parameter the snapshots' median, its standard error and 95 % half-width
/// the larger of the snapshots' stated errors combined (as correlated at
/// 0.5 between snapshots: part of each one's error is the instrument's) and
/// their scatter (Student's t at K − 1 dof). The result's `snapshots` holds
/// the answers and, per parameter, whether they agree within their error
/// bars (a χ² test at p < 0.01).
///
/// With `measurements` (one per calibration, in their order) and `mask`,
/// the combination is then refitted on the measurements as one fit (one
/// ψ, each snapshot its own scene; the default preset's scene fit, detail
/// and fine passes): the geometry the joint fit's, σ and every error bar
/// the combination's; `snapshots["joint_fit_from"]` keeps the combination.
///
/// Args:
///     calibrations: two or more Calibration (from `calibrate`, or
///         `Calibration.from_json` of `cassi calibrate -o` files).
///     measurements: None, or the snapshots' measurements (2-D arrays).
///     mask: the nominal coded aperture they were calibrated with (with
///         `measurements`).
///     bands, stride: as they were calibrated with (with `measurements`).
///
/// Returns:
///     Calibration: usable wherever one is (`reconstruct(calibration=)`).
///
/// Raises:
///     InputError (a ValueError): fewer than two, or calibrations of
///         different models or presets, or curvatures held at different
///         values (named by position; curvatures fitted in every
///         calibration combine like the other parameters); measurements not one per calibration, without a
///         mask, of the wrong shape, or of calibrations whose preset or
///         model has no scene fit.
///
/// The GIL is released while the joint fit runs.
#[pyfunction]
#[pyo3(signature = (calibrations, *, measurements=None, mask=None, bands=28, stride=2.0))]
pub fn combine_calibrations(
    py: Python<'_>,
    calibrations: Vec<Bound<'_, PyCalibration>>,
    measurements: Option<Vec<Bound<'_, PyAny>>>,
    mask: Option<&Bound<'_, PyAny>>,
    bands: usize,
    stride: f64,
) -> PyResult<PyCalibration> {
    let refs: Vec<&calib::Calibration> = calibrations.iter().map(|c| &c.get().inner).collect();
    let combined = calib::combine_snapshots(&refs, &calib::CombineParams::default())
        .map_err(|e| value_error(py, e.to_string()))?;
    let Some(measurements) = measurements else {
        return Ok(PyCalibration { inner: combined });
    };
    let Some(mask) = mask else {
        return Err(value_error(
            py,
            "measurements: the joint fit needs the mask",
        ));
    };
    if measurements.len() != refs.len() {
        return Err(value_error(
            py,
            format!(
                "measurements: {} for {} calibrations; give one per calibration, in their order",
                measurements.len(),
                refs.len()
            ),
        ));
    }
    let preset = match Preset::by_name(&combined.preset, stride)
        .and_then(|p| p.with_dispersion_a2(combined.parameters.a2))
        .map_err(|e| value_error(py, e.to_string()))?
    {
        Preset::Default(p) => p,
        Preset::Paper(_) => {
            return Err(value_error(
                py,
                format!(
                    "measurements: the calibrations are the {} preset's; the joint fit is the \
                     default preset's scene fit",
                    combined.preset
                ),
            ));
        }
    };
    let mask = arrays::frame(mask, "mask")?;
    let ys = measurements
        .iter()
        .enumerate()
        .map(|(i, y)| arrays::frame(y, &format!("measurements[{i}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let refit = || -> Result<calib::Calibration, Failure> {
        for (i, y) in ys.iter().enumerate() {
            validate_measurement(y, &format!("measurements[{i}]"))?;
        }
        let problems = ys
            .iter()
            .enumerate()
            .map(|(i, y)| {
                CalibrationProblem::nominal(y, &mask, bands, stride, combined.model)
                    .and_then(|p| p.holding(combined.band_offsets.as_ref(), combined.band_spread))
                    .and_then(|p| p.validate().map(|()| p))
                    .map_err(|e| {
                        Failure::Study(anyhow::Error::new(e).context(format!("measurements[{i}]")))
                    })
            })
            .collect::<Result<Vec<_>, Failure>>()?;
        Ok(calib::refit_jointly(&combined, &problems, &preset)?)
    };
    let inner = py.detach(|| catch(refit))?;
    Ok(PyCalibration { inner })
}

enum Message {
    Stage(StageReport),
    // boxed: a calibration is several times a stage report's size
    Done(Box<Result<calib::Calibration, Failure>>),
}

/// Self-calibration: estimates the mismatch ψ between the nominal model and
/// the instrument that took the measurement `y`, from `y` and the nominal
/// `mask` alone (no ground truth).
///
/// Args:
///     y: the measurement, 2-D (rows, detector cols), rows = the mask's rows.
///     mask: the nominal coded aperture, 2-D (rows, cols), values in [0, 1].
///     bands: spectral bands of the scene (the standard instrument: 28).
///     stride: nominal dispersion, detector pixels per band (2).
///     model: the dispersion model fitted: "dispersed-mask" (the default
///         preset's default: continuous a1 and α, the mask sampled once where each band lands,
///         with the optical blur σ and standard errors whose coverage is
///         measured), "subpixel" (the mask interpolated twice; its own
///         measured floors; the paper preset's default), "crisp-cells"
///         (dispersed-mask with each side of a pixel's mask edge blurred
///         from where it lies: σ unbiased with the scene known, but the
///         blind fit reads it high; not the default) or "rounded" (the
///         paper's discrete model).
///     preset: "default" (ours) or "paper" (the paper's Algorithm 1).
///     dispersion_a2: the dispersion's curvature the calibration holds, px
///         per band² (band k at a1·k + a2·k²): the prism's design value;
///         not fitted; default preset only.
///     blur_pass: the default preset's last stage, the blur pass (σ
///         refitted alone on the crisp-cell model with GAP-TV's texture,
///         the geometry held, on the middle quarter of the rows): None
///         (the default) keeps the preset's own — on for "default", none
///         for "paper"; False leaves it out (the CLI's --no-blur-pass);
///         True asks for it (an error with the paper preset). It reads σ
///         nearer the truth on blurred instruments and above all on smooth
///         scenes at a pose off the pixel grid, where the scene fit reads σ
///         about 0.07 px low. Since stop 62 it starts from the texture
///         fit's σ; about 0.35–0.6 s on a 256×256 frame.
///     search_rows: the rows the default preset's search stages (pose from
///         several starts, dispersion hypotheses, their pose re-fits) run
///         on: None keeps the preset's own (the middle 256 rows of a taller
///         frame, or its most detailed 256 where those hold more than twice
///         the middle's detail), an int N that many rows, "all" every row (the
///         CLI's --search-rows); the texture and scene fits always use
///         every row. An error with the paper preset.
///     ridge_probes: after the default preset's scene fit, profile its
///         objective a pixel and a half along the dx–a1 and dy–α ridges
///         (each end band moved, the other held), refit from any dip, and
///         report the ends that score within 1 % of the answer (the CLI's
///         --ridge-probes; `Calibration.ridge_probes`); the answer is kept,
///         the errors reach the alternatives. An error with the paper
///         preset.
///     fit_curvature: fit the dispersion's curvature a2 too, in the scene
///         fit's fine pass, from `dispersion_a2` (the CLI's
///         --fit-curvature); a local refinement from that value: give a
///         prism's design curvature where it is known. An error with the
///         paper preset.
///     band_offsets: each band's position along the dispersion, px, one per
///         band (a monochromator scan of the camera), held while the rest
///         is fitted (the CLI's --band-offsets): the table's own line
///         through band 0 is removed (dx and a1 fit it), the rest held in
///         every candidate and kept in the result
///         (`Calibration.band_offsets`), which `reconstruct(calibration=…)`
///         holds too. Default preset only.
///     band_spread: where each band's light lies along the dispersion in
///         the fitted model (the CLI's --band-spread): "uniform" (evenly
///         over the bands' spacing: a spectrum constant within each band),
///         "point" or "linear" (a hat between the neighbours); None: the
///         CLI's default ("uniform" for the default preset's dispersed-mask
///         and crisp-cell models, "point" otherwise); kept in the result
///         (`Calibration.band_spread`). Spread bands: default preset only.
///     progress: called with a dict {name, evaluations, seconds,
///         parameters, score} as each stage finishes.
///
/// Returns:
///     Calibration: parameters, standard_errors, trade_offs, stages,
///     seconds, evaluations, score, nominal_score.
///
/// Raises:
///     InputError (a ValueError): wrong shapes (named, with the shape got
///         and wanted), NaN/±Inf, a measurement without light, a mask
///         without code, an unknown model or preset.
///     KeyboardInterrupt: Ctrl-C; the calibration stops at its next score
///         (the library's cancel flag) and the call returns.
///
/// The GIL is released while the calibration runs.
#[pyfunction]
#[pyo3(signature = (y, mask, *, bands=28, stride=2.0, model=None, preset="default", dispersion_a2=0.0, blur_pass=None, search_rows=None, ridge_probes=false, fit_curvature=false, band_offsets=None, band_spread=None, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate(
    py: Python<'_>,
    y: &Bound<'_, PyAny>,
    mask: &Bound<'_, PyAny>,
    bands: usize,
    stride: f64,
    model: Option<&str>,
    preset: &str,
    dispersion_a2: f64,
    blur_pass: Option<bool>,
    search_rows: Option<Bound<'_, PyAny>>,
    ridge_probes: bool,
    fit_curvature: bool,
    band_offsets: Option<Vec<f64>>,
    band_spread: Option<&str>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<PyCalibration> {
    let mut preset = Preset::by_name(preset, stride)
        .and_then(|p| p.with_dispersion_a2(dispersion_a2))
        .map_err(|e| value_error(py, e.to_string()))?;
    match blur_pass {
        None => {}
        Some(false) => preset = preset.without_blur_pass(),
        Some(true) => {
            preset = preset
                .with_blur_pass()
                .map_err(|e| value_error(py, format!("blur_pass: {e}")))?;
        }
    }
    if let Some(rows) = search_rows {
        // an int or a string, read by the CLI's one parser as Python
        // writes it (str(16) = "16"; -3, 2.5 and "some" are refused there)
        let rows = Preset::search_rows_from_str(&rows.str()?.to_string())
            .map_err(|e| value_error(py, format!("search_rows: {e}")))?;
        preset = preset
            .with_search_rows(rows)
            .map_err(|e| value_error(py, format!("search_rows: {e}")))?;
    }
    if fit_curvature {
        preset = preset
            .with_fitted_curvature()
            .map_err(|e| value_error(py, format!("fit_curvature: {e}")))?;
    }
    if ridge_probes {
        preset = preset
            .with_ridge_probes()
            .map_err(|e| value_error(py, format!("ridge_probes: {e}")))?;
    }
    let model = match model {
        Some(name) => params::model(py, name)?,
        None => preset.default_model(),
    };
    let offsets = match band_offsets {
        None => None,
        Some(table) => {
            preset
                .check_band_offsets()
                .map_err(|e| value_error(py, format!("band_offsets: {e}")))?;
            if table.len() != bands {
                return Err(value_error(
                    py,
                    format!(
                        "band_offsets: {} values, expected {bands} (one position per band)",
                        table.len()
                    ),
                ));
            }
            Some(
                cassi_core::optics::BandOffsets::from_table(&table, stride)
                    .map_err(|e| value_error(py, format!("band_offsets: {e}")))?,
            )
        }
    };
    let spread: cassi_core::optics::BandSpread = match band_spread {
        Some(name) => name
            .parse()
            .map_err(|e| value_error(py, format!("band_spread: {e}")))?,
        None => preset.default_band_spread(model),
    };
    preset
        .check_band_spread(spread)
        .map_err(|e| value_error(py, format!("band_spread: {e}")))?;
    let measurement = arrays::frame(y, "measurement y")?;
    let mask = arrays::frame(mask, "mask")?;
    // the CLI's checks, before any work
    let checks = || -> Result<(), Failure> {
        validate_measurement(&measurement, "measurement y")?;
        if let MaskCode::Uniform(v) = mask_code(&mask, "mask")? {
            return Err(Failure::Core(cassi_core::CassiError::Meaningless {
                what: "mask".into(),
                reason: format!("every pixel transmits {v}: there is no code to calibrate against"),
            }));
        }
        CalibrationProblem::nominal(&measurement, &mask, bands, stride, model)?.validate()?;
        Ok(())
    };
    catch(checks)?;

    // The work runs on its own thread so that this one can answer Ctrl-C
    // at once; it raises the problem's cancel flag, which fails the
    // calibration's next score.
    let cancel = Arc::new(AtomicBool::new(false));
    let cancel_worker = Arc::clone(&cancel);
    let (tx, rx) = mpsc::channel::<Message>();
    let worker = std::thread::Builder::new()
        .name("cassi-calibrate".into())
        .spawn(move || {
            let stages = tx.clone();
            let result = catch(|| {
                let mut problem =
                    CalibrationProblem::nominal(&measurement, &mask, bands, stride, model)?
                        .with_cancel(&cancel_worker);
                problem = problem.holding(offsets.as_ref(), spread)?;
                let mut on_stage = |s: &StageReport| {
                    let _ = stages.send(Message::Stage(s.clone()));
                };
                Ok(calib::calibrate(&problem, &preset, &mut on_stage)?)
            });
            let _ = tx.send(Message::Done(Box::new(result)));
        })
        .map_err(|e| value_error(py, format!("cannot start the calibration thread: {e}")))?;
    let mut rx = rx;
    loop {
        let (back, message) = py.detach(move || {
            let m = rx.recv_timeout(Duration::from_millis(50));
            (rx, m)
        });
        rx = back;
        match message {
            Ok(Message::Stage(s)) => {
                if let Some(cb) = &progress {
                    cb.call1((stage_dict(py, &s)?,))?;
                }
            }
            Ok(Message::Done(result)) => {
                let _ = worker.join();
                return Ok(PyCalibration { inner: (*result)? });
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                return Err(Failure::Internal(
                    "the calibration thread ended without a result".into(),
                )
                .into());
            }
        }
        if let Err(interrupt) = py.check_signals() {
            cancel.store(true, Ordering::Relaxed);
            // the worker stops at its next score; wait for it (without the
            // GIL) so that no calibration outlives the call
            let _ = py.detach(move || worker.join());
            return Err(interrupt);
        }
    }
}
