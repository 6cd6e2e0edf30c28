import json,sys
tol={'dx':0.05,'dy':0.05,'theta_deg':0.05,'a1':0.005,'alpha_deg':0.1,'blur_sigma_px':0.05}
for f in sys.argv[1:]:
    c=json.load(open(f))['cases']
    for kind in ('random','aligned_blur'):
        k=[x for x in c if x['kind']==kind]
        if not k: continue
        rms={p:round((sum(x['error'][p]**2 for x in k)/len(k))**.5,4) for p in tol}
        w={p:sum(abs(x['error'][p])<=tol[p] for x in k) for p in tol}
        print(f.split('/')[-1][:22].ljust(22),kind[:7],len(k),'all6',sum(x['all_within_tolerance'] for x in k),w,rms)
