"""Overhead of the Python bindings over the same library calls, and the
zero-copy input path.

    python python/bench/bindings.py [--quick] [-o bench/results/python_bindings.json]

Times, interleaved (Python call, then the same Rust call, repeated):
  * GAP-TV (100 iterations, nominal model) on a 256×256×28 synthetic scene
    measured through a random mask: `cassi.reconstruct` against the library's
    `Method::solve` timed inside Rust on the same converted inputs;
  * one self-calibration (default preset and model) of that scene
    with the paper's mismatch: `cassi.calibrate` against `calib::calibrate`;
  * `Operator.forward` on a C-contiguous float32 cube against the operator's
    `apply` alone, and on a float64 cube (the converting path).
and checks the zero-copy path: the address the library reads is the
array's own, and the peak of traced allocations during `forward` is the
output alone. Writes medians, ratios, the machine and its load.
"""

import argparse
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time
import tracemalloc

import numpy as np

import cassi
from cassi import _cassi

REPO = pathlib.Path(__file__).resolve().parents[2]


def machine():
    cpu = "unknown"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True,
                                text=True).stdout.strip()
    except OSError:
        commit = None
    return {
        "cpu": cpu,
        "threads": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "cassi": cassi.__version__,
        "commit": commit,
    }


def interleaved(python_call, rust_call, repeats):
    """Seconds of each, alternating so drift in the machine's load hits both."""
    py, rs = [], []
    for _ in range(repeats):
        t = time.perf_counter()
        python_call()
        py.append(time.perf_counter() - t)
        rs.extend(rust_call())
    return py, rs


def summary(name, py, rs, what):
    p, r = statistics.median(py), statistics.median(rs)
    q = lambda xs: statistics.quantiles(xs, n=4) if len(xs) >= 2 else [xs[0]] * 3
    return {
        "name": name,
        "what": what,
        "runs": len(py),
        "python_s": py,
        "rust_s": rs,
        "python_median_s": p,
        "rust_median_s": r,
        "python_min_s": min(py),
        "rust_min_s": min(rs),
        "python_quartiles_s": q(py),
        "rust_quartiles_s": q(rs),
        "overhead_ratio": p / r,
        "overhead_ratio_of_minima": min(py) / min(rs),
        "overhead_percent": 100.0 * (p / r - 1.0),
    }


def peak_traced_bytes(f):
    tracemalloc.start()
    tracemalloc.reset_peak()
    try:
        f()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats (a smoke run)")
    ap.add_argument("-o", "--output", default=str(REPO / "bench" / "results" / "python_bindings.json"))
    args = ap.parse_args()
    gap_runs, cal_runs, fwd_runs = (2, 1, 20) if args.quick else (15, 9, 200)

    load_before = os.getloadavg()
    scene = cassi.synthetic_scene(256, 256, 28, seed=0)
    mask = cassi.random_mask(256, 256, seed=1)
    y_nominal = cassi.simulate(scene, mask)
    y_paper = cassi.simulate_physical(scene, mask, "paper", oversample=2)
    results = []

    # warm-up of both paths (thread pools, page faults); not timed
    cassi.reconstruct(y_nominal, mask)
    _cassi._rust_reconstruct_seconds(y_nominal, mask, "gap-tv", repeats=1)
    py, rs = interleaved(
        lambda: cassi.reconstruct(y_nominal, mask),
        lambda: _cassi._rust_reconstruct_seconds(y_nominal, mask, "gap-tv", repeats=1),
        gap_runs,
    )
    results.append(summary("gap-tv", py, rs,
                           "GAP-TV, 100 iterations, 256x256x28, nominal rounded model: "
                           "cassi.reconstruct vs Method::solve in Rust"))
    print(json.dumps({k: v for k, v in results[-1].items() if not k.endswith("_s")}))

    if not args.quick:
        cassi.calibrate(y_paper, mask)
        _cassi._rust_calibrate_seconds(y_paper, mask, repeats=1)
    py, rs = interleaved(
        lambda: cassi.calibrate(y_paper, mask),
        lambda: _cassi._rust_calibrate_seconds(y_paper, mask, repeats=1),
        cal_runs,
    )
    results.append(summary("calibrate", py, rs,
                           "self-calibration, default preset and model, 256x256x28, paper "
                           "mismatch through a 2x physical instrument: cassi.calibrate vs "
                           "calib::calibrate in Rust"))
    print(json.dumps({k: v for k, v in results[-1].items() if not k.endswith("_s")}))

    op = cassi.Operator(mask)
    x = np.ascontiguousarray(scene, dtype=np.float32)
    py, rs = interleaved(lambda: op.forward(x), lambda: op._rust_forward_seconds(x, repeats=1),
                         fwd_runs)
    results.append(summary("forward", py, rs,
                           "Operator.forward on a C-contiguous float32 256x256x28 cube (shape and "
                           "NaN/Inf check, output allocation) vs the operator's apply alone"))
    x64 = x.astype(np.float64)
    py64, rs64 = interleaved(lambda: op.forward(x64), lambda: op._rust_forward_seconds(x, repeats=1),
                             max(fwd_runs // 4, 5))
    results.append(summary("forward-float64", py64, rs64,
                           "Operator.forward on a float64 cube (converted to a float32 copy "
                           "first) vs the operator's apply alone"))
    for r in results[-2:]:
        print(json.dumps({k: v for k, v in r.items() if not k.endswith("_s")}))

    address, copied = _cassi._input_address(x)
    out_bytes = int(np.prod(op.measurement_shape)) * 4
    zero_copy = {
        "input_bytes": x.nbytes,
        "output_bytes": out_bytes,
        "library_reads_the_array_in_place": bool(address == x.ctypes.data and not copied),
        "forward_peak_traced_bytes_float32_input": peak_traced_bytes(lambda: op.forward(x)),
        "forward_peak_traced_bytes_float64_input": peak_traced_bytes(lambda: op.forward(x64)),
    }
    print(json.dumps(zero_copy))
    load_after = os.getloadavg()

    record = {
        "benchmark": "Python bindings: overhead over the same Rust calls, zero-copy input",
        "command": "python python/bench/bindings.py" + (" --quick" if args.quick else ""),
        "machine": machine(),
        "load_average_1_5_15_min": {"before": load_before, "after": load_after},
        "results": results,
        "zero_copy": zero_copy,
    }
    out = pathlib.Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=1) + "\n")
    print(f"→ {out}")


if __name__ == "__main__":
    sys.exit(main())
