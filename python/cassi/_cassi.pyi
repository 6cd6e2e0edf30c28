"""Type stubs of the compiled extension cassi._cassi (re-exported by cassi)."""

from os import PathLike
from typing import Any, Callable, Dict, List, Literal, Mapping, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
F32Array = npt.NDArray[np.float32]
Path = Union[str, "PathLike[str]"]
Model = Literal["rounded", "subpixel", "dispersed-mask"]
#: None (nominal), "nominal", "paper", a mapping of PARAMETERS keys to values, or a Calibration
MismatchLike = Union[None, str, Mapping[str, float], "Calibration"]

__version__: str
#: The mismatch parameters' keys, in the library's registry order:
#: dx, dy (px), theta_deg (°), a1 (px/band), alpha_deg (°), blur_sigma_px (px).
PARAMETERS: List[str]
#: The PARAMETERS the presets fit: all but the curvature a2, which they hold.
CALIBRATED_PARAMETERS: List[str]
#: The stages that choose between two answers, by what they are:
#: nominal_a1_restart (a held curvature's fits again from the nominal a1) and
#: nominal_start (the scene fit's first pass again from the nominal
#: dispersion) → the stage name in Calibration.stages, whose passed_over
#: is the answer not kept.
CHOOSING_STAGES: Dict[str, str]
PARAMETER_UNITS: Dict[str, str]
#: Every reconstruction method of the library's registry: (name, kind).
METHODS: List[Tuple[str, str]]
#: The methods this build can run (the learned ones need the nets feature).
ITERATIVE_METHODS: List[str]
PRESETS: List[str]
NETS_BUILT: bool
METRIC_DEFINITIONS: str

class CassiError(Exception):
    """Base class of every error cassi raises."""

class InputError(CassiError, ValueError):
    """Input cassi cannot use: shape, range, NaN/±Inf, unknown name, file content."""

class InputTypeError(CassiError, TypeError):
    """An argument of a kind cassi cannot read (complex, object, string arrays)."""

class FileNotFound(CassiError, FileNotFoundError):
    """A file, or the folder of an output file, does not exist."""

class FileError(CassiError, OSError):
    """The operating system refused or failed a read or a write."""

class Operator:
    """The CASSI forward model y = B(σ) A(ψ) x of one instrument.

    A C-contiguous float32 input is read in place; other real arrays are
    converted. Shapes and finiteness are checked.
    """

    def __init__(
        self,
        mask: ArrayLike,
        bands: int = 28,
        stride: float = 2.0,
        mismatch: MismatchLike = None,
        model: Optional[Model] = None,
        **params: float,
    ) -> None: ...
    @property
    def cube_shape(self) -> Tuple[int, int, int]:
        """(bands, rows, cols) of the cubes `forward` takes."""
    @property
    def measurement_shape(self) -> Tuple[int, int]:
        """(rows, detector cols) of the measurements `forward` makes."""
    @property
    def bands(self) -> int: ...
    @property
    def stride(self) -> float: ...
    @property
    def model(self) -> Model: ...
    @property
    def mismatch(self) -> Dict[str, float]:
        """ψ keyed by PARAMETERS."""
    def forward(self, x: ArrayLike) -> F32Array:
        """y = A x: cube (bands, rows, cols) → measurement (rows, detector cols)."""
    def adjoint(self, y: ArrayLike) -> F32Array:
        """x = Aᵀ y: measurement (rows, detector cols) → cube (bands, rows, cols)."""

class Calibration:
    """The result of `calibrate`."""

    @property
    def preset(self) -> str: ...
    @property
    def model(self) -> Model: ...
    @property
    def parameters(self) -> Dict[str, float]:
        """The estimated ψ keyed by PARAMETERS (px, °, px/band)."""
    @property
    def reconstruction_parameters(self) -> Dict[str, float]:
        """What reconstruct(calibration=) uses: `parameters`, or with blur_sigma_px the calibrated
        model's own fit where the calibration kept it (its model_blur_sigma_px)."""
    @property
    def standard_errors(self) -> Dict[str, Optional[float]]:
        """Standard error per parameter; None where not estimated."""
    @property
    def intervals_95(self) -> Dict[str, Optional[float]]:
        """Half-width of the 95 % interval per parameter (heavy-tailed errors:
        wider than 2 × the standard error); None where not estimated."""
    @property
    def ranges_95(self) -> Dict[str, Optional[Tuple[float, float]]]:
        """95 % interval per parameter as (low, high): the estimate ∓ its half-width, the low
        end raised to what the parameter can take (a blur's 0); None where not estimated."""
    @property
    def trade_offs(self) -> List[Tuple[str, str, float]]:
        """(key_a, key_b, correlation) of parameters pinned only in combination."""
    @property
    def stages(self) -> List[Dict[str, Any]]:
        """Each stage: {name, evaluations, seconds, parameters, score, passed_over}; passed_over
        is {parameters, score} of the answer a choosing stage did not keep (a held curvature's
        restart from the nominal a1), else None."""
    @property
    def ridge_probes(self) -> Optional[Dict[str, Any]]:
        """What the ridge probes found (calibrate(..., ridge_probes=True)), else None:
        {"ends": [{ridge, moved, step_px, dip_relative_objective, parameters, distance_px,
        relative_objective, alternative}], "profiles": [{ridge, moved, steps_px,
        relative_objective}]}; an end with alternative True is a placement the data do not
        rule out (within 1 % of the answer's objective, half a pixel or more away)."""
    @property
    def score(self) -> float: ...
    @property
    def nominal_score(self) -> float: ...
    @property
    def seconds(self) -> float: ...
    @property
    def evaluations(self) -> int: ...
    @property
    def band_offsets(self) -> Optional[List[float]]:
        """The bands' departures from the straight dispersion the calibration held
        (calibrate(..., band_offsets=…)), px, one per band; else None."""
    @property
    def band_spread(self) -> str:
        """Where each band's light lies along the dispersion in the fitted model:
        "point", "uniform" or "linear" (calibrate(..., band_spread=…))."""
    @property
    def snapshots(self) -> Optional[Dict[str, Any]]:
        """Where this combines several snapshots (`combine_calibrations`): each
        snapshot's parameters and, per parameter, whether they agree; else None."""
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str) -> "Calibration":
        """Reads `to_json` output or a `cassi calibrate -o calib.json` file."""

def simulate(
    scene: ArrayLike,
    mask: ArrayLike,
    mismatch: MismatchLike = None,
    *,
    model: Optional[Model] = None,
    stride: float = 2.0,
    noise: bool = True,
    photon_peak: Optional[float] = 1e5,
    read_noise: float = 0.01,
    seed: int = 0,
    **params: float,
) -> F32Array:
    """A snapshot of `scene` through the discrete instrument model (+ noise)."""

def simulate_physical(
    scene: ArrayLike,
    mask: ArrayLike,
    mismatch: MismatchLike = None,
    *,
    stride: float = 2.0,
    oversample: int = 4,
    blur_sigma_px: Optional[float] = None,
    blur_slope_px_per_nm: float = 0.0,
    detector: Optional[Tuple[int, int]] = None,
    adc_bits: Optional[int] = None,
    halo: Optional[Tuple[float, float]] = None,
    dispersion_a2: float = 0.0,
    dispersion_step: Optional[Tuple[int, float]] = None,
    band_spread: str = "point",
    wavelengths_nm: Optional[Sequence[float]] = None,
    noise: bool = True,
    photon_peak: Optional[float] = 1e5,
    read_noise: float = 0.01,
    seed: int = 0,
    **params: float,
) -> F32Array:
    """A snapshot through the physical (oversampled, blurred) instrument;
    `halo` = (share, sigma_px): that share of the light in a wider skirt;
    `dispersion_a2`: band k lands a1·k + a2·k² px along the dispersion;
    `dispersion_step` = (k, px): bands k onward land px further along it;
    `band_spread`: "point" (each band at its position), "uniform" or
    "linear" (its light spread between its neighbours' positions, as a
    real camera's continuous spectrum is)."""

def calibrate(
    y: ArrayLike,
    mask: ArrayLike,
    *,
    bands: int = 28,
    stride: float = 2.0,
    model: Optional[Model] = None,
    preset: Literal["default", "paper"] = "default",
    dispersion_a2: float = 0.0,
    blur_pass: bool | None = None,
    search_rows: int | Literal["all"] | None = None,
    ridge_probes: bool = False,
    fit_curvature: bool = False,
    band_offsets: Optional[Sequence[float]] = None,
    band_spread: Optional[str] = None,
    progress: Optional[Callable[[Dict[str, Any]], object]] = None,
) -> Calibration:
    """Self-calibration from the measurement and the nominal mask alone;
    `blur_pass`: None keeps the preset's own last stage (the default preset's
    blur pass: σ refitted on the crisp-cell model); False leaves it out; True asks
    for it (an error with the paper preset). `search_rows`: the rows the search
    stages run on (None: the preset's own, the middle 256 of a taller frame; N;
    "all"); an error with the paper preset. `ridge_probes`: profile the scene fit's
    objective along the dx–a1 and dy–α ridges and report placements it does not rule out
    (Calibration.ridge_probes); an error with the paper preset. `fit_curvature`: fit the
    dispersion's curvature a2 too, in the scene fit's fine pass, from `dispersion_a2` (a
    local refinement: give a prism's design curvature where known); an error with the
    paper preset. `band_offsets`: each band's position along the dispersion (px, one per
    band; a monochromator scan), its own line through band 0 removed and the rest held in
    every candidate (Calibration.band_offsets; reconstruct(calibration=…) holds it too);
    an error with the paper preset. `band_spread`: "uniform", "point" or "linear" — each
    band's light spread along the dispersion in the fitted model, as a camera's continuous
    spectrum spreads it (Calibration.band_spread; reconstructions hold it too); None: the
    CLI's default, "uniform" for the default preset's dispersed-mask and crisp-cell
    models, "point" otherwise; a spread is an error with the paper preset."""

def combine_calibrations(
    calibrations: List[Calibration],
    *,
    measurements: Optional[List[ArrayLike]] = None,
    mask: Optional[ArrayLike] = None,
    bands: int = 28,
    stride: float = 2.0,
) -> Calibration:
    """Several snapshots' calibrations of one instrument combined: each parameter
    the snapshots' median, its error the larger of their stated errors combined
    (correlated at 0.5) and their scatter (Student's t); `snapshots` on the result
    says where they agree. With `measurements` (one per calibration, in order) and
    `mask`, the combination is refitted on them as one fit (one ψ, each snapshot
    its own scene): the geometry the joint fit's, σ and the error bars the
    combination's; `snapshots["joint_fit_from"]` keeps the combination."""

@overload
def reconstruct(
    y: ArrayLike,
    mask: ArrayLike,
    *,
    method: str = "gap-tv",
    weights: Optional[Path] = None,
    calibration: Optional[Calibration] = None,
    mismatch: MismatchLike = None,
    model: Optional[Model] = None,
    bands: int = 28,
    stride: float = 2.0,
    iterations: Optional[int] = None,
    strength: Optional[float] = None,
    progress: Optional[Callable[[Dict[str, Any]], object]] = None,
    return_info: Literal[False] = False,
    **params: float,
) -> F32Array: ...
@overload
def reconstruct(
    y: ArrayLike,
    mask: ArrayLike,
    *,
    method: str = "gap-tv",
    weights: Optional[Path] = None,
    calibration: Optional[Calibration] = None,
    mismatch: MismatchLike = None,
    model: Optional[Model] = None,
    bands: int = 28,
    stride: float = 2.0,
    iterations: Optional[int] = None,
    strength: Optional[float] = None,
    progress: Optional[Callable[[Dict[str, Any]], object]] = None,
    return_info: Literal[True],
    **params: float,
) -> Tuple[F32Array, Dict[str, Any]]: ...
def metrics(truth: ArrayLike, estimate: ArrayLike) -> Dict[str, float]:
    """{psnr, psnr_band_mean, ssim, sam_deg} as the library defines them."""

def evaluate(
    out: Path,
    *,
    scenes: Optional[Path] = None,
    synthetic: Optional[int] = None,
    size: int = 256,
    limit: Optional[int] = None,
    mask: Optional[Path] = None,
    mask_var: Optional[str] = None,
    methods: Sequence[str] = ("gap-tv",),
    weights: Optional[Mapping[str, Path]] = None,
    weights_dir: Optional[Path] = None,
    iterations: Optional[int] = None,
    preset: str = "default",
    mismatch: Union[None, str, Mapping[str, float], "Calibration"] = None,
    model: Literal["rounded", "subpixel"] = "rounded",
    stride: float = 2.0,
    noise: bool = True,
    photon_peak: Optional[float] = 1e5,
    read_noise: float = 0.01,
    seed: int = 0,
    resume: bool = False,
    shard: Union[None, str, Tuple[int, int]] = None,
    merge: Optional[int] = None,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    **params: float,
) -> Dict[str, Any]:
    """The four-scenario study of `cassi eval` into `out`; its summary.
    `shard=(K, N)` runs scenes K, K + N, … into out/shards/K-of-N/;
    `merge=N` writes the report of N finished shards."""

def load(
    path: Path,
    var: Optional[str] = None,
    *,
    kind: Literal["array", "cube", "frame"] = "array",
    layout: Literal["auto", "brc", "rcb"] = "auto",
) -> F32Array:
    """A variable of a .mat (v5/v7.3), .npy or .npz file as float32."""

def save(path: Path, array: ArrayLike, var: Optional[str] = None) -> None:
    """Writes .npy/.npz/.mat (v5, single) by extension, atomically."""

def synthetic_scene(
    rows: int = 256,
    cols: int = 256,
    bands: int = 28,
    seed: int = 0,
    wavelengths_nm: Optional[Sequence[float]] = None,
) -> F32Array:
    """The library's procedural hyperspectral scene (bands, rows, cols)."""

def random_mask(rows: int = 256, cols: int = 256, open_fraction: float = 0.5, seed: int = 1) -> F32Array:
    """An i.i.d. random binary mask (rows, cols)."""

def _input_address(x: ArrayLike) -> Tuple[int, bool]: ...
def _rust_reconstruct_seconds(
    y: ArrayLike, mask: ArrayLike, method: str = ..., bands: int = ..., stride: float = ...,
    iterations: Optional[int] = ..., repeats: int = ...,
) -> List[float]: ...
def _rust_calibrate_seconds(
    y: ArrayLike, mask: ArrayLike, bands: int = ..., stride: float = ..., model: str = ...,
    preset: str = ..., repeats: int = ...,
) -> List[float]: ...
def _panic_for_test() -> None: ...
