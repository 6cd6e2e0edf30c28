"""PyTorch CPU reference timing of the networks cassi-nets implements, the
counterpart of `cargo bench -p cassi-nets --bench forward`.

For each network: load the stored weights (strict), check the output against
the stored PyTorch test vector (max |Δ| ≤ 1e-4; a network that fails is not
timed), then time one forward at batch 1, 256×256 (HSI-SDeCNN: one 1×7×256²
stack, sigma 10/255), 2 threads, eval + inference_mode, median of 5 after
1 warm-up. Each network runs in its own child process so its peak RSS
(VmHWM) is its own. Writes bench/results/nets_forward_pytorch.json (or
$CASSI_BENCH_OUT). Shared data: $CASSI_SHARED_DATA, else ../shared/data
from the repository root.

Run: python bench/pytorch_forward.py [network ...]   (networks: mst_s mst_l hdnet hsi_sdecnn)
"""
import json
import os
import pathlib
import subprocess
import sys
import time

THREADS = 2
RUNS = 5
TOLERANCE = 1e-4  # README §2: about 50–100× the float32 rounding noise
NETWORKS = ["mst_s", "mst_l", "hdnet", "hsi_sdecnn"]
CHILD_FLAG = "--child"
REPO = pathlib.Path(__file__).resolve().parent.parent


def shared_data():
    return pathlib.Path(os.environ.get("CASSI_SHARED_DATA") or REPO.parent / "shared" / "data")


def load_average():
    with open("/proc/loadavg") as f:
        return float(f.read().split()[0])


def cpu_model():
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return "unknown"


def memory_mib(field):
    """A /proc/self/status memory line (kB) in MiB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0
    return None


def reset_peak_rss():
    """Resets VmHWM to the current RSS (Linux 4.0+), as the Rust bench does,
    so the peak excludes the interpreter's start-up; returns VmRSS in MiB."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass
    return memory_mib("VmRSS")


# ---------------------------------------------------------------- child side


def run_network(name, nets):
    """Check, then time, one network in this process; returns its row."""
    import numpy as np
    import torch
    from safetensors.torch import load_file

    import pytorch_nets as pn

    torch.set_num_threads(THREADS)
    rss_at_start = reset_peak_rss()  # after importing torch, before weights

    def load(model, file):
        model.load_state_dict(load_file(str(nets / file)), strict=True)
        return model.eval()

    def npy(rel):
        return torch.from_numpy(np.load(nets / rel))

    def max_diff(got, want):
        assert got.shape == want.shape, f"{name}: shape {tuple(got.shape)} vs {tuple(want.shape)}"
        return float((got - want).abs().max())

    n = 256
    checks = {}
    if name in ("mst_s", "mst_l", "hdnet"):
        y = np.load(nets / "common/y.npy")
        mask = np.load(nets / "common/mask.npy")
        h_np, phi_np = pn.toolbox_inputs(y, mask)
        assert pn.sha256_of_data(h_np) == pn.H_SHA256, "H differs from README §1 (SHA-256)"
        assert pn.sha256_of_data(phi_np) == pn.PHI_SHA256, "Phi differs from README §1 (SHA-256)"
        h, phi = torch.from_numpy(h_np), torch.from_numpy(phi_np)
        if name == "hdnet":
            net = load(pn.HDNet(), "hdnet/hdnet_seed0.safetensors")
            forward, inputs = (lambda: net(h)), f"H 1×28×{n}×{n}"
        else:
            ctor, file = {
                "mst_s": (pn.mst_s, "mst_s/mst_s.safetensors"),
                "mst_l": (pn.mst_l, "mst_l/mst_l_seed0.safetensors"),
            }[name]
            net = load(ctor(), file)
            forward, inputs = (lambda: net(h, phi)), f"H 1×28×{n}×{n}, Phi 1×28×{n}×{phi.shape[3]}"
        with torch.inference_mode():
            checks[f"{name}/out.npy"] = max_diff(forward(), npy(f"{name}/out.npy"))
        # The timed input is the checked one.
    elif name == "hsi_sdecnn":
        net = load(pn.HSISDeCNN(), "hsi_sdecnn/hsi_sdecnn_seed0.safetensors")
        with torch.inference_mode():
            for stem, sigma in (("", "sigma"), ("odd_", "odd_sigma")):
                got = net(npy(f"hsi_sdecnn/{stem}in.npy"), npy(f"hsi_sdecnn/{sigma}.npy"))
                checks[f"hsi_sdecnn/{stem}out.npy"] = max_diff(got, npy(f"hsi_sdecnn/{stem}out.npy"))
        # The timed input: cube bands 11–17 (a 7-band stack centred on band 14), full 256².
        stack = npy("common/cube.npy")[:, 11:18].contiguous()
        sigma = torch.full((1, 1, 1, 1), 10.0 / 255.0)
        forward, inputs = (lambda: net(stack, sigma)), f"1×7×{n}×{n} (one band of a cube)"
    else:
        raise SystemExit(f"unknown network {name!r}; known: {' '.join(NETWORKS)}")

    worst = max(checks.values())
    for k, d in checks.items():
        print(f"{name}: {k}: max |Δ| = {d:.3e} (tolerance {TOLERANCE:.0e})", file=sys.stderr)
    if not worst <= TOLERANCE:  # also catches NaN
        raise SystemExit(f"{name}: output does not match the reference (max |Δ| = {worst:.3e}); not timed")

    runs = []
    with torch.inference_mode():
        forward()  # warm-up
        for _ in range(RUNS):
            t = time.perf_counter()
            forward()
            runs.append(time.perf_counter() - t)
    med = sorted(runs)[RUNS // 2]
    peak = memory_mib("VmHWM")
    print(f"{name}: median {med:.3f} s over {RUNS} runs {[round(r, 3) for r in runs]}; "
          f"peak RSS {peak:.0f} MiB (at start {rss_at_start:.0f})", file=sys.stderr)
    return {
        "network": name, "input": inputs, "median_s": med, "runs_s": runs,
        "peak_rss_mib": peak, "rss_at_start_mib": rss_at_start,
        "max_abs_diff_vs_reference": worst, "checks": checks,
    }


# --------------------------------------------------------------- parent side


def main(argv):
    if argv[:1] == [CHILD_FLAG]:
        print(json.dumps(run_network(argv[1], shared_data() / "nets")))
        return 0
    nets = shared_data() / "nets"
    if not nets.is_dir():
        print(f"no {nets} (set CASSI_SHARED_DATA): nothing to time", file=sys.stderr)
        return 1
    wanted = [a for a in argv if not a.startswith("-")] or NETWORKS
    import torch  # only for the version string; the children do the work

    load_before = load_average()
    rows, failed = [], []
    for name in wanted:
        child = subprocess.run([sys.executable, __file__, CHILD_FLAG, name], stdout=subprocess.PIPE, text=True)
        if child.returncode != 0:
            failed.append(name)
            rows.append({"network": name, "error": "failed or did not match the reference; not timed"})
        else:
            rows.append(json.loads(child.stdout))
    out = pathlib.Path(os.environ.get("CASSI_BENCH_OUT") or REPO / "bench/results/nets_forward_pytorch.json")
    doc = {
        "benchmark": "PyTorch reference: one forward pass per network, batch 1, f32, CPU",
        "machine": {"cpu": cpu_model(), "threads": THREADS},
        # Other work on the machine inflates the times; the 1-minute load
        # average before and after the runs says how much there was.
        "load_average_1min": {"before": load_before, "after": load_average()},
        "torch": torch.__version__,
        "protocol": f"output checked against the stored vector (max |Δ| ≤ {TOLERANCE:g}), then median of "
                    f"{RUNS} after 1 warm-up; torch.set_num_threads({THREADS}), model.eval(), torch.inference_mode()",
        "memory": "each network in its own process; peak_rss_mib: that process's VmHWM over loading, the "
                  "check, warm-up and runs (reset after importing torch); rss_at_start_mib: VmRSS then "
                  "(interpreter + torch libraries)",
        "results": rows,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n")
    print(f"wrote {out}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
