import json,sys,statistics as S
a=json.load(open(sys.argv[1]))['cases'];b=json.load(open(sys.argv[2]))['cases']
def six(c): return c['all_within_tolerance']
def rho(c): return c.get('rho') is None or c['rho']>=0.95
n=len(b)
print('cases',n)
print('all six  base',sum(six(c) for c in a[:n]),'new',sum(six(c) for c in b))
print('rho>=95  base',sum(rho(c) for c in a[:n]),'new',sum(rho(c) for c in b))
print('median s base',round(S.median(c['seconds'] for c in a[:n]),2),'new',round(S.median(c['seconds'] for c in b),2))
srch=lambda c: sum(s['seconds'] for s in c['stages'][:4])
print('search stages s base',round(S.median(srch(c) for c in a[:n]),2),'new',round(S.median(srch(c) for c in b),2))
same=0
for x,y in zip(a,b):
    e1={k:round(v,3) for k,v in x['error'].items()}; e2={k:round(v,3) for k,v in y['error'].items()}
    if x['estimate']==y['estimate']: same+=1
    if six(x)!=six(y) or rho(x)!=rho(y):
        print(x['scene'][5:15], x['kind'][:7], 'six',six(x),six(y),'rho',round(x.get('rho') or 0,3),round(y.get('rho') or 0,3), e1, e2)
print('identical estimates',same)
for p in ['dx','dy','theta_deg','a1','alpha_deg','blur_sigma_px']:
    r1=(sum(c['error'][p]**2 for c in a[:n])/n)**.5; r2=(sum(c['error'][p]**2 for c in b)/n)**.5
    print(p,'rmse',round(r1,4),round(r2,4))
