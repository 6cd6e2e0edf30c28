#!/usr/bin/env python3
"""Each CAVE scene's band-to-band registration: the sub-pixel shift of every band against band 14
(phase correlation, parabolic peak), its least-squares slope per band along x and y, and the
light of band 0 against band 27. A scene whose bands drift apart sideways would read, blind, as a
dispersion change; stop 66 measured that they do not drift enough to matter.

    python3 bench/band_registration.py SCENE [SCENE ...]   (names as in ../shared/data/scenes/cave_NAME.npy)

Needs numpy; the scenes are read from $CASSI_SHARED_DATA/scenes (default ../shared/data/scenes).
"""
import os
import sys

import numpy as np

SCENES = os.path.join(os.environ.get("CASSI_SHARED_DATA", "../shared/data"), "scenes")

def shift_est(a,b):
    A=np.fft.fft2(a-a.mean());B=np.fft.fft2(b-b.mean())
    R=A*np.conj(B); R/=np.abs(R)+1e-12
    r=np.real(np.fft.ifft2(R))
    i,j=np.unravel_index(np.argmax(r),r.shape)
    n,m=r.shape
    def par(lo,c,hi):
        den=lo-2*c+hi
        return (lo-hi)/(2*den) if den!=0 else 0
    di=par(r[(i-1)%n,j],r[i,j],r[(i+1)%n,j]); dj=par(r[i,(j-1)%m],r[i,j],r[i,(j+1)%m])
    y=i+di; x=j+dj
    if y>n/2: y-=n
    if x>m/2: x-=m
    return -x,-y
for name in sys.argv[1:]:
    c=np.load(os.path.join(SCENES, f'cave_{name}.npy'))
    ref=c[14]
    xs=[];ys=[]
    for k in range(28):
        x,y=shift_est(ref,c[k]); xs.append(x); ys.append(y)
    xs=np.array(xs); ys=np.array(ys); k=np.arange(28)
    px=np.polyfit(k,xs,1); py=np.polyfit(k,ys,1)
    light=c.reshape(28,-1).mean(1)
    print(f'{name:24s} x slope {px[0]:+.4f} px/band (b0 {xs[0]:+.3f} b27 {xs[27]:+.3f})  y slope {py[0]:+.4f}  light b0/b27 {light[0]/light[27]:.2f}')
    print('   x:',' '.join(f'{v:+.2f}' for v in xs))
