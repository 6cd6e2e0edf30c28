import json,sys,statistics as st
files=sys.argv[1:]
cases=[c for f in files for c in json.load(open(f))['cases'] if c.get('psnr_db')]
ds=['0']+list(cases[0]['psnr_db']['III_sigma_margin'].keys())
def rho(ii,iii,iv): return (iii-ii)/(iv-ii) if iv-ii>0 else None
print(len(cases),'cases')
for d in ds:
    out=[]
    for kind in ('random','aligned_blur'):
        cs=[c for c in cases if c['kind']==kind]
        iii=[c['psnr_db']['III_calibrated'] if d=='0' else c['psnr_db']['III_sigma_margin'][d] for c in cs]
        r=[rho(c['psnr_db']['II_nominal'],x,c['psnr_db']['IV_true']) for c,x in zip(cs,iii)]
        n=sum(1 for x in r if x is not None and x>=0.95)
        dp=st.mean(x-c['psnr_db']['III_calibrated'] for c,x in zip(cs,iii))
        worst=min(x-c['psnr_db']['III_calibrated'] for c,x in zip(cs,iii))
        out.append('%s ρ≥95%% %d/%d ΔPSNR mean %+.4f worst %+.4f'%(kind[:7],n,len(cs),dp,worst))
    print('δ %-6s'%d,' | '.join(out))
