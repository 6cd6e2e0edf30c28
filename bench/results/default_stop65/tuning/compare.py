#!/usr/bin/env python3
"""Blur-pass settings against the default on the same aligned tuning instruments: per case the σ
error and ρ before -> after, then ρ >= 95 %, all six within tolerance and σ RMSE.

    python3 compare.py BASE.json RUN.json [RUN.json ...]
"""
import json,sys
base=json.load(open(sys.argv[1]))
for f in sys.argv[2:]:
    d=json.load(open(f))
    print('==',f)
    nb=nv=0; sb=sv=0
    for a,b in zip(base['cases'],d['cases']):
        assert a['scene']==b['scene'] and a['seed']==b['seed']
        ea,eb=a['error']['blur_sigma_px'],b['error']['blur_sigma_px']
        ra,rb=a.get('rho'),b.get('rho')
        nb+= ra is not None and ra>=0.95; nv+= rb is not None and rb>=0.95
        sb+=a['all_within_tolerance']; sv+=b['all_within_tolerance']
        print(f"  {a['kind'][:7]} {a['scene'][5:18]:13s} σ {a['truth']['blur_sigma_px']:.3f} err {ea:+.3f} -> {eb:+.3f}  rho {ra if ra is None else round(ra,3)} -> {rb if rb is None else round(rb,3)}")
    n=len(base['cases'])
    rmsa=(sum(c['error']['blur_sigma_px']**2 for c in base['cases'])/n)**.5; rmsb=(sum(c['error']['blur_sigma_px']**2 for c in d['cases'])/n)**.5
    print(f'  rho>=0.95 {nb} -> {nv} of {n}; all six {sb} -> {sv}; σ RMSE {rmsa:.4f} -> {rmsb:.4f}')
