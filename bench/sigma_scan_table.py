#!/usr/bin/env python3
"""The blur pass's σ scan (stop 70's diagnostic build, bench/results/default_stop70/blur_pass_probes/
sigma_scan_diagnostic.rs.txt): per case the truth, the pass's start, its answer, and where the
cold-solved objective over σ = 0, 0.05, …, 0.8 px is lowest (its local minima; the ratio of σ = 0's
score to the lowest). Usage: bench/sigma_scan_table.py LOG"""
import re,sys,json
log=open(sys.argv[1]).read().split('\n')
cases=[];cur=None
for l in log:
  if l.startswith('scan start'):
    parts=l.split()
    start=float(parts[2]); pts=[tuple(map(float,p.split(':'))) for p in parts[3:]]
    cur={'start':start,'pts':pts}
  elif l.startswith('scan found'):
    cur['found']=float(l.split()[2]); cur['fscore']=float(l.split()[4])
  elif l.startswith('  truth') and cur is not None:
    cur['truth']=float(re.search(r'blur ([0-9.]+) px',l).group(1)); cases.append(cur); cur=None
for c in cases:
  pts=c['pts']; am=min(pts,key=lambda p:p[1])
  # local minima
  mins=[pts[i][0] for i in range(len(pts)) if (i==0 or pts[i][1]<pts[i-1][1]) and (i==len(pts)-1 or pts[i][1]<pts[i+1][1])]
  print(f"truth {c['truth']:.3f} start {c['start']:.3f} found {c['found']:.3f} scan argmin {am[0]:.2f} minima {mins} s0/smin {pts[0][1]/am[1]:.4f}")
