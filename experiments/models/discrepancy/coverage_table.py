#!/usr/bin/env python3
"""Coverage of the effect intervals of a coverage-study work folder, as reported (widened
for neighbouring bins and to at least the sandwich sd) and as sampled (each interval shrunk about its mean by its
sd_inflation, which undoes the widening up to the coordinate transform).

    python3 experiments/models/discrepancy/coverage_table.py <DIR>   # <DIR>: --work of the study
"""
import json,glob,sys,math,collections,os
W=sys.argv[1]
rows=collections.defaultdict(list)
for f in sorted(glob.glob(W+'/diagnoses/*/diagnosis.json')):
    cid=f.split('/')[-2]
    fam=cid.rsplit('-c',1)[0]
    rows[fam].append((cid,json.load(open(f))))
import tomllib
cases={c['id']:c for c in tomllib.load(open(os.path.join(os.path.dirname(os.path.abspath(__file__)),'coverage','cases.toml'),'rb'))['case']}
print('| family | parameter | covered, widened (rms z) | covered, as sampled (rms z) | widening |')
print('|---|---|---|---|---|')
tot=[0,0,0]
for fam,lst in rows.items():
    params=collections.defaultdict(list)
    for cid,d in lst:
        tr=cases[cid].get('truth',{})
        for k,v in d['effect_parameters'].items():
            if k not in tr: continue
            t=tr[k]; m=v['mean']; lo,hi=v['q2.5'],v['q97.5']; f=v.get('sd_inflation',1.0)
            sd=(hi-lo)/3.92
            # as sampled: shrink about the mean by the widening
            lo0=m-(m-lo)/f; hi0=m+(hi-m)/f
            params[k].append((lo<=t<=hi,(m-t)/sd,lo0<=t<=hi0,(m-t)/(sd/f),f))
    for k,l in params.items():
        n=len(l); c=sum(x[0] for x in l); c0=sum(x[2] for x in l)
        rz=math.sqrt(sum(x[1]**2 for x in l)/n); rz0=math.sqrt(sum(x[3]**2 for x in l)/n)
        tot[0]+=c; tot[1]+=c0; tot[2]+=n
        print(f'| {fam} | {k} | {c}/{n} ({rz:.2f}) | {c0}/{n} ({rz0:.2f}) | {min(x[4] for x in l):.2f}-{max(x[4] for x in l):.2f} |')
print(f'| all | | {tot[0]}/{tot[2]} | {tot[1]}/{tot[2]} | |')
