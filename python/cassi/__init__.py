"""cassi: coded aperture snapshot spectral imaging (CASSI).

Python bindings of the cassi Rust library (cassi-core, cassi-io): the
single-disperser CASSI forward model and its adjoint, simulation (discrete
and physical), self-calibration of the mismatch between a camera and its
nominal model, iterative reconstruction, the library's metrics and its file
formats (.mat v5/v7.3, .npy, .npz).

Conventions (the library's): cubes are (bands, rows, cols) float32, band 0
the shortest wavelength; masks and measurements are (rows, cols); angles in
degrees; the mismatch is a dict keyed by ``PARAMETERS``
(dx, dy, theta_deg, a1, alpha_deg, blur_sigma_px).

Arrays: a C-contiguous float32 ndarray is read in place (no copy); other
real arrays are converted to float32; complex/object arrays are refused
(InputTypeError); NaN/±Inf and wrong shapes are refused (InputError, a
ValueError) with the variable, the shape got and the shape wanted named.
Every error is a ``CassiError``. The GIL is released while the library
works; Ctrl-C interrupts a calibration or reconstruction.

Studies: ``evaluate`` runs the four-scenario study of ``cassi eval``; with
``shard=(K, N)`` one share of it, and ``merge=N`` writes the report of the
finished shards, so any engine (Dask, Ray, Slurm) can spread a study.
"""

from ._cassi import (
    CassiError,
    InputError,
    InputTypeError,
    FileNotFound,
    FileError,
    Operator,
    Calibration,
    simulate,
    simulate_physical,
    calibrate,
    combine_calibrations,
    reconstruct,
    metrics,
    evaluate,
    load,
    save,
    synthetic_scene,
    random_mask,
    PARAMETERS,
    CALIBRATED_PARAMETERS,
    CHOOSING_STAGES,
    PARAMETER_UNITS,
    METHODS,
    ITERATIVE_METHODS,
    PRESETS,
    NETS_BUILT,
    METRIC_DEFINITIONS,
    __version__,
)

__all__ = [
    "CassiError",
    "InputError",
    "InputTypeError",
    "FileNotFound",
    "FileError",
    "Operator",
    "Calibration",
    "simulate",
    "simulate_physical",
    "calibrate",
    "combine_calibrations",
    "reconstruct",
    "metrics",
    "evaluate",
    "load",
    "save",
    "synthetic_scene",
    "random_mask",
    "PARAMETERS",
    "CALIBRATED_PARAMETERS",
    "CHOOSING_STAGES",
    "PARAMETER_UNITS",
    "METHODS",
    "ITERATIVE_METHODS",
    "PRESETS",
    "NETS_BUILT",
    "METRIC_DEFINITIONS",
    "__version__",
]
