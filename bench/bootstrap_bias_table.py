#!/usr/bin/env python3
"""Stop 71's geometry bootstrap diagnostic, from its log: each random pose's bootstrap bias (the
fine pass run again on GAP-TV's scene re-imaged at the answer, less the answer; the log's
"bootstrap bias" line before the case) against the base record's error; the correlation of the
two in dx, and the errors of the bootstrap's own answer (the answer plus its bias) — within
tolerance, RMSE and mean. Usage: bench/bootstrap_bias_table.py PROBE.log BASE.json"""
import math
import re
import sys

from held_out_pool import cases

GEOMETRY = ["dx", "dy", "theta_deg", "a1", "alpha_deg"]


def main(log_path, base_path):
    by_seed = {c["seed"]: c for c in cases(base_path).values() if c["kind"] == "random"}
    tol = next(iter(by_seed.values()))["tolerances"]
    rows, bias = [], None
    for line in open(log_path):
        m = re.match(r"bootstrap bias dx (\S+) dy (\S+) θ (\S+) a1 (\S+) α (\S+)", line)
        if m:
            bias = dict(zip(GEOMETRY, map(float, m.groups())))
        m = re.match(r"\S+\s+\S+\s+random\s+seed (\d+)", line)
        if m and bias is not None:
            rows.append((by_seed[int(m.group(1))], bias))
            bias = None
    for c, b in rows:
        print(f"{c['scene'][5:27]:22s} {c['seed']} dx {c['error']['dx']:+.3f} bias {b['dx']:+.4f} "
              f"→ {c['error']['dx'] + b['dx']:+.3f}   a1 {c['error']['a1']:+.4f} → {c['error']['a1'] + b['a1']:+.4f}")
    n = len(rows)
    xs = [b["dx"] for _, b in rows]
    ys = [c["error"]["dx"] for c, _ in rows]
    mx, my = sum(xs) / n, sum(ys) / n
    cov = sum((x - mx) * (y - my) for x, y in zip(xs, ys))
    corr = cov / math.sqrt(sum((x - mx) ** 2 for x in xs) * sum((y - my) ** 2 for y in ys))
    print(f"{n} random poses; correlation of the bootstrap's dx bias with the answer's dx error: {corr:+.3f}")
    for p in GEOMETRY:
        before = sum(abs(c["error"][p]) <= tol[p] for c, _ in rows)
        after = sum(abs(c["error"][p] + b[p]) <= tol[p] for c, b in rows)
        print(f"  {p}: within {before} → {after} (the bootstrap's own answer)")
    geo = lambda err: all(abs(err[p]) <= tol[p] for p in GEOMETRY)
    print(f"  geometry within {sum(geo(c['error']) for c, _ in rows)} → "
          f"{sum(geo({p: c['error'][p] + b[p] for p in GEOMETRY}) for c, b in rows)}")
    for p in ["dx", "a1"]:
        eb = [c["error"][p] for c, _ in rows]
        es = [c["error"][p] + b[p] for c, b in rows]
        rmse = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
        print(f"  {p} RMSE {rmse(eb):.4f} → {rmse(es):.4f}, mean {sum(eb) / n:+.4f} → {sum(es) / n:+.4f}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
