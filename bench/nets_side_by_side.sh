#!/usr/bin/env bash
# Rust vs PyTorch, one forward pass per network on this machine's CPU:
# runs `cargo bench -p cassi-nets --bench forward` and bench/pytorch_forward.py
# back to back (so both see the same load), then pairs the two JSON files into
# bench/results/nets_side_by_side.{json,md}.
#
# Run from the repository root: bench/nets_side_by_side.sh
# Reuse an existing venv with CASSI_TORCH_VENV=/path/to/venv (it must have
# torch 2.15.0, numpy and safetensors; otherwise they are installed there).
set -euo pipefail
venv=${CASSI_TORCH_VENV:-target/torch-venv}
results=$PWD/bench/results

# torch==2.15.0 from PyPI is the default (CUDA, +cu132) wheel, run here on the
# CPU only: the same wheel the reference test vectors were made with.
if ! "$venv/bin/python" -c 'import numpy, safetensors, torch; assert torch.__version__.startswith("2.15.0")' 2>/dev/null; then
  [[ -x "$venv/bin/python" ]] || python3 -m venv "$venv"
  "$venv/bin/pip" install -q torch==2.15.0 numpy safetensors
fi

# Explicit absolute outputs: both benchmarks read CASSI_BENCH_OUT, and cargo
# runs the bench from the crate directory.
CASSI_BENCH_OUT=$results/nets_forward.json cargo bench -p cassi-nets --bench forward
CASSI_BENCH_OUT=$results/nets_forward_pytorch.json "$venv/bin/python" bench/pytorch_forward.py
python3 bench/nets_side_by_side.py "$results/nets_forward.json" "$results/nets_forward_pytorch.json"
cat "$results/nets_side_by_side.md"
