#!/usr/bin/env python3
"""A blur-pass probe against a base record, case by case (same scene and seed): the true σ, the
texture fit's σ, both σ errors, both all-six verdicts and whether the geometry is bitwise the
base's. Usage: bench/sigma_probe_compare.py BASE.json PROBE.json"""
import json,sys
base=json.load(open(sys.argv[1])); probe=json.load(open(sys.argv[2]))
B={(c['scene'],c['seed']):c for c in base['cases']}
tol=base['tolerances']['blur_sigma_px']
n=0; wb=wp=0; rows=[]
for c in probe['cases']:
  b=B.get((c['scene'],c['seed']))
  if not b: continue
  s=c['instrument_blur_sigma_px']
  eb=b['error']['blur_sigma_px']; ep=c['error']['blur_sigma_px']
  wb+=abs(eb)<=tol; wp+=abs(ep)<=tol; n+=1
  tf=[x for x in c['stages'] if x['name'].startswith('texture')][0]['parameters']['blur_sigma_px']
  same_geo=all(abs(b['estimate'][k]-c['estimate'][k])<1e-12 for k in ['dx','dy','theta_deg','a1','alpha_deg'])
  rows.append((s,tf,eb,ep,c['scene'][5:14],c['all_within_tolerance'],b['all_within_tolerance'],same_geo))
for r in sorted(rows): print("σ %.3f tf %.3f base err %+.3f probe err %+.3f %s all6 %s→%s geo_same %s"%(r[0],r[1],r[2],r[3],r[4],r[6],r[5],r[7]))
print(f"σ within base {wb}/{n} probe {wp}/{n}; all six base {sum(r[6] for r in rows)} probe {sum(r[5] for r in rows)}")
rmse=lambda v: (sum(x*x for x in v)/len(v))**0.5
print("σ RMSE base %.4f probe %.4f px; mean error base %+.4f probe %+.4f px"%(rmse([r[2] for r in rows]),rmse([r[3] for r in rows]),sum(r[2] for r in rows)/len(rows),sum(r[3] for r in rows)/len(rows)))
