# The paired table of this folder's README: rounds 36-41, stop 61's blur pass (the
# records as they stand) against stop 62's default (round 41 fresh; 36-40 re-run).
# Run: python3 bench/results/default_stop62/paired_table.py
import json,sys
import os
R=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..') + '/'
base={36:[R+'default_stop59/held_out/round36_bench_defaults.json',R+'default_stop59/held_out/round36_aligned_rerun.json'],
      37:[R+'default_stop59/held_out/round37.json'],38:[R+'default_stop59/held_out/round38.json'],
      39:[R+'default_stop60/held_out/round39.json'],40:[R+'default_stop61/held_out/round40.json'],
      41:[R+'default_stop62/held_out/round41_stop61_blur_pass.json']}
new={r:R+'default_stop62/held_out/rerun/round%d_stop62.json'%r for r in range(36,41)}
new[41]=R+'default_stop62/held_out/round41.json'
G=['dx','dy','theta_deg','a1','alpha_deg']
tot={}
def add(k,v): tot[k]=tot.get(k,0)+v
for r in sorted(new):
    try: nb=json.load(open(new[r]))['cases']
    except Exception: continue
    b={}
    for f in base[r]:
        for c in json.load(open(f))['cases']:
            key=(c['scene'],c['seed'])
            if f.endswith('aligned_rerun.json') or key not in b: b[key]=c
    line={}
    geo_diff=0
    for c in nb:
        o=b[(c['scene'],c['seed'])]
        kind='random' if c['kind'].startswith('random') else 'aligned'
        if any(c['estimate'][p]!=o['estimate'][p] for p in G): geo_diff+=1
        for tag,x in (('old',o),('new',c)):
            e=x['error']['blur_sigma_px']
            add((kind,tag,'n'),1); add((kind,tag,'sw'),abs(e)<=0.05); add((kind,tag,'all'),x['all_within_tolerance']); add((kind,tag,'sq'),e*e)
            add((kind,tag,'cov1'),abs(e)<=x['uncertainty']['blur_sigma_px']); add((kind,tag,'cov95'),abs(e)<=x['interval_95']['blur_sigma_px'])
            line[(kind,tag)]=line.get((kind,tag),0)+x['all_within_tolerance']
    print(r, 'geometry differs in',geo_diff, {k:v for k,v in line.items()})
for kind in ['random','aligned']:
    for tag in ['old','new']:
        n=tot.get((kind,tag,'n'),0)
        if n: print(kind,tag,'n',n,'σ within',tot[(kind,tag,'sw')],'all six',tot[(kind,tag,'all')],'σ RMSE %.4f'%((tot[(kind,tag,'sq')]/n)**.5),'σ 1σ cov %d%% 95%% cov %d%%'%(100*tot[(kind,tag,'cov1')]/n,100*tot[(kind,tag,'cov95')]/n))
