#!/usr/bin/python3
"""Summary of the alternating-process A/B runs in this folder: per configuration
the ratio of pooled medians between sides and a 95 % interval from resampling
rounds (4000 resamples, seed 1). Usage: /usr/bin/python3 summary.py <subfolder> [field]"""
import json,glob,sys,re,collections,random,statistics as st
d=sys.argv[1]; field=sys.argv[2] if len(sys.argv)>2 else 's_per_particle_step'
vals=collections.defaultdict(lambda: collections.defaultdict(list))
for f in sorted(glob.glob(d+'/*.json')):
    side,rnd=f.split('/')[-1][:-5].split('-')
    try: js=json.load(open(f))
    except Exception: continue
    for b in js['benchmarks']:
        if b.get('run_type')!='iteration': continue
        name=re.sub(r'step/particles:\d+/gridder:B/cell_order:sort_x/reorder:1/','',b['name'])
        name=re.sub(r'/threads:1/lattice:cubic/h_coefficient:1.0','',name)
        vals[name][(side,int(rnd))].append(b[field]*1e6)
random.seed(1)
for key in sorted(vals):
    v=vals[key]
    print(key, ' '.join(f"{s}={st.median([x for (ss,r),xs in v.items() if ss==s for x in xs]):.3f}" for s in ('old','emu','hw','base','new') if any(ss==s for ss,_ in v)))
    for a,b in (('old','emu'),('old','hw'),('emu','hw'),('base','new')):
        rounds=sorted({r for s,r in v if (a,r) in v and (b,r) in v})
        if not rounds: continue
        def ratio(rs):
            A=[x for r in rs for x in v[(a,r)]]; B=[x for r in rs for x in v[(b,r)]]
            return st.median(A)/st.median(B)
        bs=sorted(ratio([random.choice(rounds) for _ in rounds]) for _ in range(4000))
        print(f"   {a}/{b} {ratio(rounds):.3f} [{bs[100]:.3f}, {bs[3899]:.3f}] rounds={len(rounds)}")
