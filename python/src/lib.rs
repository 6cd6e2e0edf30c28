//! Python bindings of the cassi library (cassi-core, cassi-io): the module
//! `cassi._cassi`, re-exported by the `cassi` package (python/cassi).
//!
//! The bindings convert and check arguments, release the GIL around the
//! library's work, catch panics (a `CassiError`, never a crash) and map the
//! library's errors to Python exceptions carrying its messages (errors.rs).
//! No science lives here.

mod arrays;
mod calibration;
mod errors;
mod learned;
mod params;
mod study;

use std::time::Instant;

use numpy::{PyArray, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use cassi_core::limits::check_elements;
use cassi_core::linop::LinearOperator;
use cassi_core::optics::{
    BandSpread, DispersionStep, Halo, ModelOperator, NoiseModel, PhysicalSpec, SimulationSpec,
    validate_mismatch_for_mask,
};
use cassi_core::recon::registry::METHODS;
use cassi_core::recon::{Method, MethodId, Model};
use cassi_core::solvers::{Control, IterationInfo};
use cassi_core::{Instrument, Mismatch, Parameter};
use cassi_io::CubeLayout;

use calibration::PyCalibration;
use errors::{Failure, compute, value_error};

/// The CASSI forward model of one instrument: the nominal `mask` moved,
/// dispersed and blurred as the mismatch says, for cubes of `bands` bands.
///
/// Args:
///     mask: the nominal coded aperture, 2-D (rows, cols), values in [0, 1].
///     bands: spectral bands of the cubes it takes (28).
///     stride: nominal dispersion, detector pixels per band (2).
///     mismatch: None (nominal), "paper", a dict of parameters (keys of
///         `cassi.PARAMETERS`: dx, dy px; theta_deg °; a1 px/band;
///         alpha_deg °; blur_sigma_px px) or a Calibration (its band
///         offsets held, where it held a table).
///     model: "rounded" (integer band offsets), "subpixel",
///         "dispersed-mask" (subpixel, the mask sampled where each band
///         lands) or "crisp-cells" (dispersed-mask, each side of a pixel's
///         mask edge blurred from where it lies); default: a
///         Calibration's own model, else "rounded".
///     **params: single mismatch parameters by key, e.g. dx=1.5.
///
/// `forward(x)` maps a cube (bands, rows, cols) to a measurement
/// (rows, detector cols); `adjoint(y)` maps back. A C-contiguous float32
/// input is read in place (no copy).
#[pyclass(name = "Operator", module = "cassi", frozen)]
pub struct PyOperator {
    op: ModelOperator,
    mismatch: Mismatch,
    model: &'static str,
    stride: f64,
}

#[pymethods]
impl PyOperator {
    #[new]
    #[pyo3(signature = (mask, bands=28, stride=2.0, mismatch=None, model=None, **params))]
    fn new(
        py: Python<'_>,
        mask: &Bound<'_, PyAny>,
        bands: usize,
        stride: f64,
        mismatch: Option<&Bound<'_, PyAny>>,
        model: Option<&str>,
        params: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let dispersion = params::model_for(py, model, mismatch)?;
        let psi = params::mismatch(py, stride, mismatch, params)?;
        // a calibration's held band offsets and spread are its instrument's
        let (offsets, spread) = mismatch
            .and_then(|m| m.cast::<PyCalibration>().ok())
            .map(|c| {
                let cal = &c.get().inner;
                (cal.band_offsets.clone(), cal.band_spread)
            })
            .unwrap_or_default();
        let mask = arrays::frame(mask, "mask")?;
        let op = compute(py, || {
            validate_mismatch_for_mask(&psi, mask.rows(), mask.cols())?;
            let model = Model::new(&mask, bands, stride, psi, dispersion)?
                .holding(offsets.as_ref(), spread)?;
            Ok(model.operator()?)
        })?;
        Ok(Self {
            op,
            mismatch: psi,
            model: dispersion.name(),
            stride,
        })
    }

    /// (bands, rows, cols) of the cubes `forward` takes.
    #[getter]
    fn cube_shape(&self) -> (usize, usize, usize) {
        self.op.cube_shape()
    }

    /// (rows, detector cols) of the measurements `forward` makes.
    #[getter]
    fn measurement_shape(&self) -> (usize, usize) {
        self.op.measurement_shape()
    }

    #[getter]
    fn bands(&self) -> usize {
        self.op.cube_shape().0
    }

    #[getter]
    fn stride(&self) -> f64 {
        self.stride
    }

    #[getter]
    fn model(&self) -> &'static str {
        self.model
    }

    /// The mismatch ψ as a dict of the registry's keys.
    #[getter]
    fn mismatch<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        params::to_dict(py, &self.mismatch)
    }

    /// y = A x: a cube (bands, rows, cols) to a measurement (rows, detector cols).
    fn forward<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let (l, h, w) = self.op.cube_shape();
        let (rows, cols) = self.op.measurement_shape();
        let input = arrays::finite_with_shape(
            x,
            "cube x",
            &[l, h, w],
            "(bands, rows, cols) for this operator",
        )?;
        apply_into(py, &input, &[rows, cols], |x, y| self.op.apply(x, y))
    }

    /// x = Aᵀ y: a measurement (rows, detector cols) to a cube (bands, rows, cols).
    fn adjoint<'py>(&self, py: Python<'py>, y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let (l, h, w) = self.op.cube_shape();
        let (rows, cols) = self.op.measurement_shape();
        let input = arrays::finite_with_shape(
            y,
            "measurement y",
            &[rows, cols],
            "(rows, detector cols) for this operator",
        )?;
        apply_into(py, &input, &[l, h, w], |y, x| self.op.adjoint(y, x))
    }

    /// Seconds of each of `repeats` applications of the library's operator
    /// alone to `x` (checked and borrowed once, outside the timing): the
    /// benchmark's reference for `forward`'s overhead.
    #[pyo3(signature = (x, repeats=20))]
    fn _rust_forward_seconds(
        &self,
        py: Python<'_>,
        x: &Bound<'_, PyAny>,
        repeats: usize,
    ) -> PyResult<Vec<f64>> {
        let (l, h, w) = self.op.cube_shape();
        let input = arrays::finite_with_shape(x, "cube x", &[l, h, w], "(bands, rows, cols)")?;
        let xs = input.slice();
        let op = &self.op;
        compute(py, || {
            let mut y = vec![0f32; op.range_len()];
            Ok((0..repeats)
                .map(|_| {
                    let t = Instant::now();
                    op.apply(xs, &mut y);
                    std::hint::black_box(&mut y);
                    t.elapsed().as_secs_f64()
                })
                .collect())
        })
    }

    fn __repr__(&self) -> String {
        let (l, h, w) = self.op.cube_shape();
        let (r, c) = self.op.measurement_shape();
        format!(
            "Operator(cube ({l}, {h}, {w}) -> measurement ({r}, {c}), model={:?}, {})",
            self.model,
            Parameter::format_all(&self.mismatch)
        )
    }
}

/// A new float32 array of `shape` filled by `f(input, out)` without the
/// GIL (the input read in place).
fn apply_into<'py>(
    py: Python<'py>,
    input: &arrays::F32Array<'_>,
    shape: &[usize],
    f: impl Fn(&[f32], &mut [f32]) + Sync,
) -> PyResult<Bound<'py, PyAny>> {
    let out = PyArray::<f32, _>::zeros(py, shape, false);
    {
        let mut rw = out.readwrite();
        let dst = rw.as_slice_mut().expect("a new array is contiguous");
        let src = input.slice();
        compute(py, || {
            f(src, dst);
            Ok(())
        })?;
    }
    Ok(out.into_any())
}

fn noise_model(
    py: Python<'_>,
    noise: bool,
    photon_peak: Option<f64>,
    read_noise: f64,
    seed: u64,
) -> PyResult<Option<NoiseModel>> {
    if !noise {
        return Ok(None);
    }
    let n = NoiseModel {
        photon_peak,
        read_noise,
        seed,
    };
    n.validate().map_err(|e| value_error(py, e.to_string()))?;
    Ok(Some(n))
}

/// Simulates a CASSI snapshot of `scene` through the instrument the
/// mismatch describes, with a discrete dispersion model (what `cassi
/// simulate --model` does).
///
/// Args:
///     scene: cube (bands, rows, cols), values in [0, 1].
///     mask: nominal coded aperture (rows, cols), the scene's size.
///     mismatch: as for `Operator` (None: nominal); **params override single keys.
///     model: "rounded", "subpixel", "dispersed-mask" or "crisp-cells" (default: a Calibration's own, else
///         "rounded").
///     stride: nominal dispersion, px per band (the nominal a1).
///     noise: add detector noise (Poisson at `photon_peak` photo-electrons at
///         the maximum, None for none, plus Gaussian read noise `read_noise`
///         electrons), seeded by `seed` (the CLI's defaults).
///
/// Returns the measurement (rows, cols + dispersion reach), float32.
#[pyfunction]
#[pyo3(signature = (scene, mask, mismatch=None, *, model=None, stride=2.0, noise=true, photon_peak=Some(1e5), read_noise=0.01, seed=0, **params))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    mask: &Bound<'py, PyAny>,
    mismatch: Option<&Bound<'py, PyAny>>,
    model: Option<&str>,
    stride: f64,
    noise: bool,
    photon_peak: Option<f64>,
    read_noise: f64,
    seed: u64,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let spec = SimulationSpec {
        mismatch: params::mismatch(py, stride, mismatch, params)?,
        model: params::model_for(py, model, mismatch)?,
        noise: noise_model(py, noise, photon_peak, read_noise, seed)?,
    };
    let scene = arrays::cube(scene, "scene")?;
    let mask = arrays::frame(mask, "mask")?;
    let y = compute(py, || {
        validate_mismatch_for_mask(&spec.mismatch, mask.rows(), mask.cols())?;
        Ok(cassi_core::optics::simulate(&scene, &mask, &spec)?)
    })?;
    arrays::frame_to_numpy(py, y)
}

/// Simulates the physical instrument (what `cassi simulate --oversample`
/// does): an `oversample`× finer grid, crisp mask squares moved by the
/// mismatch, the scene interpolated, continuous dispersion, Gaussian blur
/// σ(λ) = blur_sigma_px + blur_slope_px_per_nm·(λ − λ_c), detector pixels
/// as means of their fine pixels, an optional fixed `detector` (rows, cols)
/// and ADC of `adc_bits` bits after the noise; `halo` = (share, sigma_px)
/// puts that share of the light in a wider Gaussian skirt under the blur;
/// `dispersion_a2` curves the dispersion (band k at a1·k + a2·k² px);
/// `dispersion_step` = (k, px) moves band k and every later band px
/// further along it; `band_spread` ("point", "uniform" or "linear") spreads
/// each band's light along the dispersion between its neighbours, as a real
/// camera's continuous spectrum is. No operator of the library reproduces it
/// exactly (no inverse crime).
///
/// `blur_sigma_px` defaults to the mismatch's blur; `wavelengths_nm` to the
/// standard instrument's band centres for the scene's band count.
#[pyfunction]
#[pyo3(signature = (scene, mask, mismatch=None, *, stride=2.0, oversample=4, blur_sigma_px=None, blur_slope_px_per_nm=0.0, detector=None, adc_bits=None, halo=None, dispersion_a2=0.0, dispersion_step=None, band_spread="point", wavelengths_nm=None, noise=true, photon_peak=Some(1e5), read_noise=0.01, seed=0, **params))]
#[allow(clippy::too_many_arguments)]
fn simulate_physical<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    mask: &Bound<'py, PyAny>,
    mismatch: Option<&Bound<'py, PyAny>>,
    stride: f64,
    oversample: usize,
    blur_sigma_px: Option<f64>,
    blur_slope_px_per_nm: f64,
    detector: Option<(usize, usize)>,
    adc_bits: Option<u32>,
    halo: Option<(f64, f64)>,
    dispersion_a2: f64,
    dispersion_step: Option<(usize, f64)>,
    band_spread: &str,
    wavelengths_nm: Option<Vec<f64>>,
    noise: bool,
    photon_peak: Option<f64>,
    read_noise: f64,
    seed: u64,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut psi = params::mismatch(py, stride, mismatch, params)?;
    if let Some(b) = blur_sigma_px {
        psi.blur_sigma_px = b;
    }
    let spec = PhysicalSpec {
        oversample,
        blur_sigma_px: psi.blur_sigma_px,
        blur_slope_px_per_nm,
        detector,
        adc_bits,
        halo: halo.map(|(share, sigma_px)| Halo { share, sigma_px }),
        dispersion_a2,
        dispersion_step: dispersion_step.map(|(from_band, px)| DispersionStep { from_band, px }),
        band_spread: band_spread
            .parse::<BandSpread>()
            .map_err(|e| value_error(py, format!("band_spread: {e}")))?,
    };
    let noise = noise_model(py, noise, photon_peak, read_noise, seed)?;
    let scene = arrays::cube(scene, "scene")?;
    let mask = arrays::frame(mask, "mask")?;
    let wavelengths = match wavelengths_nm {
        Some(w) => w,
        None => {
            Instrument::with_bands(scene.bands(), stride)
                .map_err(|e| value_error(py, e.to_string()))?
                .wavelengths_nm
        }
    };
    if wavelengths.len() != scene.bands() {
        return Err(value_error(
            py,
            format!(
                "wavelengths_nm has {} entries, expected {} (one per band of the scene)",
                wavelengths.len(),
                scene.bands()
            ),
        ));
    }
    let y = compute(py, || {
        validate_mismatch_for_mask(&psi, mask.rows(), mask.cols())?;
        Ok(cassi_core::optics::simulate_physical(
            &scene,
            &mask,
            &wavelengths,
            &psi,
            &spec,
            noise.as_ref(),
        )?)
    })?;
    arrays::frame_to_numpy(py, y)
}

/// The instrument a reconstruction assumes, from `calibration` or
/// `mismatch`/`params` (not both).
fn assumed(
    py: Python<'_>,
    stride: f64,
    calibration: Option<&Bound<'_, PyCalibration>>,
    mismatch: Option<&Bound<'_, PyAny>>,
    model: Option<&str>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<(
    Mismatch,
    cassi_core::optics::DispersionModel,
    (Option<cassi_core::optics::BandOffsets>, BandSpread),
)> {
    match calibration {
        Some(cal) => {
            if mismatch.is_some() || params.is_some_and(|p| !p.is_empty()) {
                return Err(value_error(
                    py,
                    "give the instrument once: calibration= or mismatch=/parameters, not both",
                ));
            }
            let cal = &cal.get().inner;
            if let Some(m) = model
                && m != cal.model.name()
            {
                return Err(value_error(
                    py,
                    format!(
                        "model {m:?} differs from the calibration's model {:?}; leave model out \
                         to use the calibrated one",
                        cal.model.name()
                    ),
                ));
            }
            Ok((
                cal.reconstruction_parameters(),
                cal.model,
                (cal.band_offsets.clone(), cal.band_spread),
            ))
        }
        None => Ok((
            params::mismatch(py, stride, mismatch, params)?,
            params::model(py, model.unwrap_or("rounded"))?,
            (None, BandSpread::Point),
        )),
    }
}

/// Reconstructs a cube from the measurement `y`, the instrument taken to be
/// the nominal one, a calibrated one or a given mismatch.
///
/// Args:
///     y: measurement (rows, detector cols); a width differing from the
///         model's detector is cropped or zero-padded on the right.
///     mask: nominal coded aperture (rows, cols).
///     method: a name of `cassi.METHODS`: an iterative solver ("gap-tv",
///         "admm-tv", "pnp-tv") or, in a package built with the networks
///         (`cassi.NETS_BUILT`), a learned one ("mst-s", "mst-l", "hdnet",
///         "pnp-hsicnn") with `weights`.
///     weights: a learned method's checkpoint (.pth state dict or
///         .safetensors, as the MST toolbox and PnP-CASSI publish them).
///     calibration: a Calibration (its parameters and model), or None.
///     mismatch: instead of a calibration, as for `Operator`; **params too.
///     model: "rounded" (default) or "subpixel"; with a calibration, its own.
///     bands, stride: the cube's bands and the nominal dispersion.
///     iterations, strength: override the method's tuned iteration count
///         and (constant) denoising strength.
///     progress: called with a dict {iteration, max_iterations,
///         relative_residual, relative_change, elapsed_s} each iteration.
///     return_info: also return a dict {method, iterations, stop,
///         relative_residual, width_fitted, seconds}.
///
/// Returns the cube (bands, rows, cols), float32, not clipped (clip to
/// [0, 1] before scoring, as the library's metrics assume).
/// Ctrl-C stops the solver at the next iteration (KeyboardInterrupt).
#[pyfunction]
#[pyo3(signature = (y, mask, *, method="gap-tv", weights=None, calibration=None, mismatch=None, model=None, bands=28, stride=2.0, iterations=None, strength=None, progress=None, return_info=false, **params))]
#[allow(clippy::too_many_arguments)]
fn reconstruct<'py>(
    py: Python<'py>,
    y: &Bound<'py, PyAny>,
    mask: &Bound<'py, PyAny>,
    method: &str,
    weights: Option<std::path::PathBuf>,
    calibration: Option<&Bound<'py, PyCalibration>>,
    mismatch: Option<&Bound<'py, PyAny>>,
    model: Option<&str>,
    bands: usize,
    stride: f64,
    iterations: Option<usize>,
    strength: Option<f32>,
    progress: Option<Bound<'py, PyAny>>,
    return_info: bool,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (psi, dispersion, (offsets, spread)) =
        assumed(py, stride, calibration, mismatch, model, params)?;
    let id = MethodId::parse(method).map_err(|e| value_error(py, e.to_string()))?;
    // an iterative recipe, or a learned method's checked weights
    let (recipe, learned_weights) = match Method::defaults(id) {
        Some(recipe) => {
            if weights.is_some() {
                return Err(value_error(
                    py,
                    format!("weights= is for the learned methods; {id} has none"),
                ));
            }
            (Some(recipe.with_overrides(iterations, strength)), None)
        }
        None => (None, Some(learned::weights_for(py, id, weights)?)),
    };
    let measurement = arrays::frame(y, "measurement y")?;
    let mask = arrays::frame(mask, "mask")?;
    let progress = progress.map(Bound::unbind);
    let mut pending: Option<PyErr> = None;
    let started = Instant::now();
    let result = compute(py, || {
        cassi_core::optics::validate_measurement(&measurement, "measurement y")?;
        // a calibration's held band offsets and spread are its instrument's
        let model =
            Model::new(&mask, bands, stride, psi, dispersion)?.holding(offsets.as_ref(), spread)?;
        // the library's observer: Ctrl-C and the progress callback, with
        // the GIL taken for a moment each iteration
        let mut observer = |info: &IterationInfo| -> Control {
            Python::attach(|py| {
                let step = || -> PyResult<()> {
                    py.check_signals()?;
                    if let Some(cb) = &progress {
                        let d = PyDict::new(py);
                        d.set_item("iteration", info.iteration)?;
                        d.set_item("max_iterations", info.max_iterations)?;
                        d.set_item("relative_residual", info.relative_residual)?;
                        d.set_item("relative_change", info.relative_change)?;
                        d.set_item("elapsed_s", info.elapsed.as_secs_f64())?;
                        cb.call1(py, (d,))?;
                    }
                    Ok(())
                };
                match step() {
                    Ok(()) => Control::Continue,
                    Err(e) => {
                        pending = Some(e);
                        Control::Stop
                    }
                }
            })
        };
        Ok(match (&recipe, &learned_weights) {
            (Some(recipe), _) => {
                let r = recipe.solve(&measurement, &model, &mut observer)?;
                let details = (
                    r.solution_iterations,
                    format!("{:?}", r.stop),
                    r.relative_residual,
                    r.width_fitted,
                );
                (r.cube, Some(details))
            }
            (None, Some(w)) => {
                let cube = learned::reconstruct(
                    id,
                    w,
                    &measurement,
                    &model,
                    iterations,
                    strength,
                    &mut observer,
                )?;
                (cube, None)
            }
            (None, None) => unreachable!("a method is iterative or learned"),
        })
    });
    if let Some(e) = pending {
        return Err(e);
    }
    let (cube, details) = result?;
    let seconds = started.elapsed().as_secs_f64();
    let info = PyDict::new(py);
    if return_info {
        info.set_item("method", id.name())?;
        // a network has no iterations (PnP-HSICNN's count is its schedule's)
        let (iterations, stop, residual, width) = match details {
            Some((i, stop, res, width)) => (Some(i), Some(stop), Some(res), width),
            None => (None, None, None, None),
        };
        info.set_item("iterations", iterations)?;
        info.set_item("stop", stop)?;
        info.set_item("relative_residual", residual)?;
        info.set_item("width_fitted", width)?;
        info.set_item("seconds", seconds)?;
    }
    let cube = arrays::cube_to_numpy(py, cube)?;
    if return_info {
        Ok((cube, info).into_pyobject(py)?.into_any())
    } else {
        Ok(cube)
    }
}

/// PSNR, band-mean PSNR, SSIM and SAM of `estimate` against `truth`, both
/// (bands, rows, cols), as the library defines them (`cassi.METRIC_DEFINITIONS`):
/// PSNR over the whole cube with peak 1; SSIM per band with an 11×11
/// Gaussian window (σ 1.5), averaged; SAM in degrees, averaged over pixels.
/// Inputs are not clipped.
#[pyfunction]
fn metrics<'py>(
    py: Python<'py>,
    truth: &Bound<'py, PyAny>,
    estimate: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let truth = arrays::cube(truth, "truth")?;
    let estimate = arrays::cube(estimate, "estimate")?;
    let m = compute(py, || Ok(cassi_core::metrics::evaluate(&truth, &estimate)?))?;
    let d = PyDict::new(py);
    d.set_item("psnr", m.psnr)?;
    d.set_item("psnr_band_mean", m.psnr_band_mean)?;
    d.set_item("ssim", m.ssim)?;
    d.set_item("sam_deg", m.sam_deg)?;
    Ok(d)
}

fn layout(py: Python<'_>, name: &str) -> PyResult<CubeLayout> {
    match name {
        "auto" => Ok(CubeLayout::Auto),
        "brc" => Ok(CubeLayout::BandsRowsCols),
        "rcb" => Ok(CubeLayout::RowsColsBands),
        other => Err(value_error(
            py,
            format!(
                "layout '{other}': expected 'auto', 'brc' (bands, rows, cols) or 'rcb' (rows, cols, bands)"
            ),
        )),
    }
}

/// Reads a numeric variable from a .mat (v5 or v7.3), .npy or .npz file as
/// float32, checked finite.
///
/// Args:
///     path: the file.
///     var: the variable's name; None: the file must hold exactly one.
///     kind: "array" (the shape the file's own tool shows, C order),
///         "cube" ((bands, rows, cols): .mat cubes are stored (rows, cols,
///         bands), see `layout`) or "frame" ((rows, cols), singleton axes
///         dropped).
///     layout: for kind="cube": "auto" (an end axis at most half of each
///         other is the band axis, else the format's convention), "brc" or "rcb".
///
/// Raises FileNotFound (a FileNotFoundError) for a missing file and
/// InputError (a ValueError) naming the file and variable otherwise.
#[pyfunction]
#[pyo3(signature = (path, var=None, *, kind="array", layout="auto"))]
fn load<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    var: Option<&str>,
    kind: &str,
    layout: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let cube_layout = self::layout(py, layout)?;
    match kind {
        "array" => {
            let a = compute(py, || Ok(cassi_io::load_array(&path, var)?))?;
            arrays::to_numpy(py, a.data, &a.shape)
        }
        "cube" => {
            let c = compute(py, || Ok(cassi_io::load_cube(&path, var, cube_layout)?))?;
            arrays::cube_to_numpy(py, c)
        }
        "frame" => {
            let f = compute(py, || Ok(cassi_io::load_frame(&path, var)?))?;
            arrays::frame_to_numpy(py, f)
        }
        other => Err(value_error(
            py,
            format!("kind '{other}': expected 'array', 'cube' or 'frame'"),
        )),
    }
}

/// Writes `array` as float32 to a .npy, .npz or .mat (v5, single precision)
/// file chosen by the extension, atomically.
///
/// A 3-D array is a cube (bands, rows, cols): .npy/.npz store it so, .mat
/// as (rows, cols, bands) (the MATLAB benchmark convention), so
/// `load(path, kind="cube")` reads it back. Other arrays are stored with
/// their shape. `var` names the variable (.mat, .npz); default "cube" for
/// 3-D, "measurement" for 2-D, "array" otherwise.
#[pyfunction]
#[pyo3(signature = (path, array, var=None))]
fn save(
    py: Python<'_>,
    path: std::path::PathBuf,
    array: &Bound<'_, PyAny>,
    var: Option<&str>,
) -> PyResult<()> {
    let a = arrays::f32_array(array, "array")?;
    arrays::check_finite(py, &a, "array")?;
    let shape = a.shape().to_vec();
    let name = var.unwrap_or(match shape.len() {
        3 => "cube",
        2 => "measurement",
        _ => "array",
    });
    let data = a.slice();
    compute(py, || {
        if let [l, h, w] = shape[..] {
            let cube = cassi_core::Cube::from_vec(l, h, w, data.to_vec())?;
            Ok(cassi_io::save_cube(&path, &cube, name)?)
        } else {
            Ok(cassi_io::save_array(&path, name, &shape, data)?)
        }
    })
}

/// The library's procedural hyperspectral scene (what `cassi simulate
/// --synthetic` uses): (bands, rows, cols) float32 in [0, 1], the band
/// centres those of the standard instrument for `bands` bands (or
/// `wavelengths_nm`), identical for a seed on every machine.
#[pyfunction]
#[pyo3(signature = (rows=256, cols=256, bands=28, seed=0, wavelengths_nm=None))]
fn synthetic_scene<'py>(
    py: Python<'py>,
    rows: usize,
    cols: usize,
    bands: usize,
    seed: u64,
    wavelengths_nm: Option<Vec<f64>>,
) -> PyResult<Bound<'py, PyAny>> {
    let wavelengths_nm = match wavelengths_nm {
        Some(w) => w,
        None => {
            Instrument::with_bands(bands, 2.0)
                .map_err(|e| value_error(py, e.to_string()))?
                .wavelengths_nm
        }
    };
    if wavelengths_nm.len() != bands {
        return Err(value_error(
            py,
            format!(
                "wavelengths_nm has {} entries, expected bands = {bands}",
                wavelengths_nm.len()
            ),
        ));
    }
    let spec = cassi_core::synth::SceneSpec {
        rows,
        cols,
        wavelengths_nm,
        seed,
    };
    let cube = compute(py, || {
        check_elements(
            "the synthetic scene",
            &[bands, rows, cols],
            "bands × rows × cols",
        )?;
        Ok(cassi_core::synth::synthetic_scene(&spec)?)
    })?;
    arrays::cube_to_numpy(py, cube)
}

/// An i.i.d. random binary mask (rows, cols) with `open_fraction` of its
/// pixels open (what `cassi simulate --random-mask` uses).
#[pyfunction]
#[pyo3(signature = (rows=256, cols=256, open_fraction=0.5, seed=1))]
fn random_mask(
    py: Python<'_>,
    rows: usize,
    cols: usize,
    open_fraction: f64,
    seed: u64,
) -> PyResult<Bound<'_, PyAny>> {
    let mask = compute(py, || {
        check_elements("the random mask", &[rows, cols], "rows × cols")?;
        Ok(cassi_core::synth::random_binary_mask(
            rows,
            cols,
            open_fraction,
            seed,
        )?)
    })?;
    arrays::frame_to_numpy(py, mask)
}

/// The address of the first value the library reads for `x` (the same as
/// `x.ctypes.data` when `x` is used in place): for the zero-copy tests.
#[pyfunction]
fn _input_address(x: &Bound<'_, PyAny>) -> PyResult<(usize, bool)> {
    let a = arrays::f32_array(x, "x")?;
    Ok((a.data_ptr(), a.copied))
}

/// Median seconds of `repeats` runs of the library's reconstruction alone
/// (inputs already converted, no Python in the loop): the benchmark's
/// reference for the bindings' overhead.
#[pyfunction]
#[pyo3(signature = (y, mask, method="gap-tv", bands=28, stride=2.0, iterations=None, repeats=5))]
#[allow(clippy::too_many_arguments)]
fn _rust_reconstruct_seconds(
    py: Python<'_>,
    y: &Bound<'_, PyAny>,
    mask: &Bound<'_, PyAny>,
    method: &str,
    bands: usize,
    stride: f64,
    iterations: Option<usize>,
    repeats: usize,
) -> PyResult<Vec<f64>> {
    let recipe = Method::by_name(method)
        .map_err(|e| value_error(py, e.to_string()))?
        .with_overrides(iterations, None);
    let y = arrays::frame(y, "measurement y")?;
    let mask = arrays::frame(mask, "mask")?;
    compute(py, || {
        let model = Model::nominal(&mask, bands, stride, Default::default())?;
        let mut times = Vec::with_capacity(repeats);
        for _ in 0..repeats {
            let t = Instant::now();
            let r = recipe.solve(&y, &model, &mut cassi_core::solvers::Silent)?;
            times.push(t.elapsed().as_secs_f64());
            std::hint::black_box(r);
        }
        Ok(times)
    })
}

/// Seconds of `repeats` runs of the library's calibration alone.
#[pyfunction]
#[pyo3(signature = (y, mask, bands=28, stride=2.0, model="dispersed-mask", preset="default", repeats=3))]
#[allow(clippy::too_many_arguments)]
fn _rust_calibrate_seconds(
    py: Python<'_>,
    y: &Bound<'_, PyAny>,
    mask: &Bound<'_, PyAny>,
    bands: usize,
    stride: f64,
    model: Option<&str>,
    preset: &str,
    repeats: usize,
) -> PyResult<Vec<f64>> {
    let preset = cassi_core::calib::Preset::by_name(preset, stride)
        .map_err(|e| value_error(py, e.to_string()))?;
    let model = match model {
        Some(name) => params::model(py, name)?,
        None => preset.default_model(),
    };
    let y = arrays::frame(y, "measurement y")?;
    let mask = arrays::frame(mask, "mask")?;
    compute(py, || {
        let problem =
            cassi_core::calib::CalibrationProblem::nominal(&y, &mask, bands, stride, model)?;
        let mut times = Vec::with_capacity(repeats);
        for _ in 0..repeats {
            let t = Instant::now();
            let c = cassi_core::calib::calibrate(&problem, &preset, &mut |_| {})?;
            times.push(t.elapsed().as_secs_f64());
            std::hint::black_box(c);
        }
        Ok(times)
    })
}

/// A panic inside the library, for the test that panics become CassiError.
#[pyfunction]
fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    compute(py, || -> Result<(), Failure> {
        panic!("a deliberate test panic")
    })
}

#[pymodule]
fn _cassi(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    errors::register(m)?;
    m.add_class::<PyOperator>()?;
    m.add_class::<PyCalibration>()?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_physical, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::combine_calibrations, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(metrics, m)?)?;
    m.add_function(wrap_pyfunction!(study::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(save, m)?)?;
    m.add_function(wrap_pyfunction!(synthetic_scene, m)?)?;
    m.add_function(wrap_pyfunction!(random_mask, m)?)?;
    m.add_function(wrap_pyfunction!(_input_address, m)?)?;
    m.add_function(wrap_pyfunction!(_rust_reconstruct_seconds, m)?)?;
    m.add_function(wrap_pyfunction!(_rust_calibrate_seconds, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    // the registries, read from the library
    m.add(
        "PARAMETERS",
        Parameter::ALL.iter().map(|p| p.key()).collect::<Vec<_>>(),
    )?;
    // the ones the presets fit (they hold the curvature a2 where given)
    m.add(
        "CALIBRATED_PARAMETERS",
        Parameter::CALIBRATED
            .iter()
            .map(|p| p.key())
            .collect::<Vec<_>>(),
    )?;
    // the names of the stages that choose between two answers (their
    // `passed_over` names the other), for finding them in `stages`
    let choosing = PyDict::new(py);
    choosing.set_item(
        "nominal_a1_restart",
        cassi_core::calib::NOMINAL_A1_RESTART_STAGE,
    )?;
    choosing.set_item("nominal_start", cassi_core::calib::NOMINAL_START_STAGE)?;
    m.add("CHOOSING_STAGES", choosing)?;
    let units = PyDict::new(py);
    for p in Parameter::ALL {
        units.set_item(p.key(), p.unit())?;
    }
    m.add("PARAMETER_UNITS", units)?;
    let methods = PyList::empty(py);
    for spec in &METHODS {
        methods.append((spec.name, format!("{:?}", spec.kind).to_lowercase()))?;
    }
    m.add("METHODS", methods)?;
    m.add(
        "ITERATIVE_METHODS",
        cassi_core::recon::registry::names_of(cassi_core::recon::MethodKind::Iterative)
            .collect::<Vec<_>>(),
    )?;
    m.add("PRESETS", cassi_core::calib::PRESET_NAMES.to_vec())?;
    m.add("NETS_BUILT", learned::BUILT)?;
    m.add(
        "METRIC_DEFINITIONS",
        cassi_core::metrics::METRIC_DEFINITIONS,
    )?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
