import json,sys
A=json.load(open(sys.argv[1]))['cases'];B=json.load(open(sys.argv[2]))['cases']
tol={'dx':0.05,'dy':0.05,'theta_deg':0.05,'a1':0.005,'alpha_deg':0.1,'blur_sigma_px':0.05}
for a,b in zip(A,B):
    assert a['seed']==b['seed']
    e=a['error'];f=b['error']
    bad=lambda x:''.join(k[0] if abs(x[k])>tol[k] else '.' for k in tol)
    print(a['scene'][5:15].ljust(10),a['seed'],a['kind'][:7], 'dx %+.3f %+.3f  a1 %+.4f %+.4f  dy %+.3f %+.3f  th %+.3f %+.3f  sig %+.3f %+.3f  %s %s'%(e['dx'],f['dx'],e['a1'],f['a1'],e['dy'],f['dy'],e['theta_deg'],f['theta_deg'],e['blur_sigma_px'],f['blur_sigma_px'],bad(e),bad(f)))
