"""Summary table of json/<actor>_<case>.json (robust_eval.py): success, AML, ASL, outcomes, low-mass successes."""
import json, glob, os
rows = {}
for f in sorted(glob.glob('/tmp/robust/json/r*_*.json')):
    n = os.path.basename(f)[:-5]
    if n.endswith('lhdeval'): continue
    d = json.load(open(f))
    if 'aggregate' not in d: continue
    a = d['aggregate']
    rows[n] = d
    print(f"{n:28s} succ {d['success_rate_incl_errors']:.3f} aml {a['aml']:5.1f} [succ-only {d['mean_kg_successes'] or 0:5.1f}, min {d['min_kg_successes'] or 0:5.1f}, <24kg {d['successes_under_24kg']:2d}] "
          f"asl {a['asl']:.2f} t {a['elapsed_s']:.2f} tilt>5 {a['tilt_over_5deg_rate']:.2f} maxtilt {max(e.get('max_tilt_deg',0) for e in d['episodes_detail']):5.1f} "
          f"{d['outcomes']} byslope " + " ".join(f"{k}:{v['success_rate']:.2f}/{v['aml']:.0f}" for k, v in d['by_slope'].items()))
