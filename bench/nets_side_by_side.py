"""Pairs the Rust and the PyTorch forward benchmarks by network name and
writes bench/results/nets_side_by_side.{json,md}. Standard library only, so
it runs with any python3.

Usage: python3 bench/nets_side_by_side.py [RUST_JSON PYTORCH_JSON]
(defaults: bench/results/nets_forward.json, bench/results/nets_forward_pytorch.json)
"""
import json
import pathlib
import sys

results = pathlib.Path(__file__).resolve().parent / "results"
rust_path, torch_path = (
    map(pathlib.Path, sys.argv[1:3]) if len(sys.argv) >= 3
    else (results / "nets_forward.json", results / "nets_forward_pytorch.json")
)
rust, torch = (json.loads(p.read_text()) for p in (rust_path, torch_path))
torch_rows = {r["network"]: r for r in torch["results"]}

rows = []
# Rust rows in their order; the *_mask_guidance_reused rows have no PyTorch
# counterpart (the PyTorch model recomputes the mask guidance every call).
for r in rust["results"]:
    t = torch_rows.get(r["network"], {})
    tm = t.get("median_s")
    rows.append({
        "network": r["network"],
        "input": r["input"],
        "rust_median_s": r["median_s"],
        "pytorch_median_s": tm,
        "ratio_pytorch_over_rust": tm / r["median_s"] if tm else None,
        "rust_peak_rss_mib": r.get("peak_rss_mib"),
        "pytorch_peak_rss_mib": t.get("peak_rss_mib"),
        "pytorch_rss_at_start_mib": t.get("rss_at_start_mib"),
        "pytorch_max_abs_diff_vs_reference": t.get("max_abs_diff_vs_reference"),
        "pytorch_error": t.get("error"),
    })

doc = {
    "benchmark": "one forward pass per network, batch 1, f32, CPU: cassi-nets (Rust) vs PyTorch",
    "machine": {"rust": rust["machine"], "pytorch": torch["machine"]},
    # Runs at different loads are not comparable; both are kept.
    "load_average_1min": {"rust": rust["load_average_1min"], "pytorch": torch["load_average_1min"]},
    "torch": torch.get("torch"),
    "protocol": {"rust": rust["protocol"], "pytorch": torch["protocol"]},
    "sources": [str(rust_path), str(torch_path)],
    "results": rows,
}
(results / "nets_side_by_side.json").write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n")


def f(x, fmt):
    return "—" if x is None else format(x, fmt)


def load(d):
    return f"{d.get('before')} → {d.get('after')}"


md = [
    "# Network forward pass: cassi-nets (Rust) vs PyTorch, CPU",
    "",
    f"Machine: {rust['machine']['cpu']}, {rust['machine']['threads']} threads (Rust) / "
    f"{torch['machine']['cpu']}, {torch['machine']['threads']} threads (PyTorch {torch.get('torch')}).",
    f"1-minute load average before → after: Rust {load(rust['load_average_1min'])}, "
    f"PyTorch {load(torch['load_average_1min'])}.",
    "Batch 1, 256×256 (HSI-SDeCNN: one 1×7×256² stack), float32, median of 5 after 1 warm-up,",
    "each network in its own process. PyTorch's peak RSS includes its libraries "
    "(RSS after `import torch` in brackets).",
    "",
    "| network | Rust median (s) | PyTorch median (s) | PyTorch / Rust | Rust peak RSS (MiB) | PyTorch peak RSS (MiB) |",
    "|---|---|---|---|---|---|",
]
for r in rows:
    at_start = r["pytorch_rss_at_start_mib"]
    torch_rss = f(r["pytorch_peak_rss_mib"], ".0f") + (f" ({at_start:.0f})" if at_start else "")
    md.append(
        f"| {r['network']} | {r['rust_median_s']:.3f} | {f(r['pytorch_median_s'], '.3f')} "
        f"| {f(r['ratio_pytorch_over_rust'], '.2f')} | {f(r['rust_peak_rss_mib'], '.0f')} | {torch_rss} |"
    )
md.append("")
(results / "nets_side_by_side.md").write_text("\n".join(md))
print(f"wrote {results / 'nets_side_by_side.json'} and nets_side_by_side.md", file=sys.stderr)
