#!/usr/bin/env python3
"""Stop 71's ridge-scan diagnostic, from its log: per random pose, where along dx–a1 (t px of dx,
a1 − t/27: band 27 held) the fine pass's objective and each probe objective (white noise; a white
flat-spectrum texture imaged at the answer) are lowest over t = −0.12 … +0.12, and the sign of
each texture probe's slope across the scan (toward +t or −t). Usage: bench/ridge_scan_table.py LOG"""
import re
import sys


def main(log_path):
    toward = {"+t": 0, "-t": 0}
    n = 0
    for line in open(log_path):
        if not line.startswith("ridge scan"):
            continue
        points = re.findall(r"t ([+-]\d\.\d\d) data (\S+) noise (\S+) noise (\S+) texture (\S+) texture (\S+)", line)
        ts = [float(p[0]) for p in points]
        cols = list(zip(*[[float(v) for v in p[1:]] for p in points]))
        lowest = [ts[min(range(len(ts)), key=col.__getitem__)] for col in cols]
        slopes = ["+t" if col[-1] < col[0] else "-t" for col in cols[3:]]
        for s in slopes:
            toward[s] += 1
        n += 1
        print(f"lowest at t: data {lowest[0]:+.2f}, noise {lowest[1]:+.2f} {lowest[2]:+.2f}, "
              f"texture {lowest[3]:+.2f} {lowest[4]:+.2f}; texture probes fall toward {' '.join(slopes)}")
    print(f"{n} scans; texture probes falling toward +t (dx up, a1 down): {toward['+t']}, toward −t: {toward['-t']}")


if __name__ == "__main__":
    main(sys.argv[1])
