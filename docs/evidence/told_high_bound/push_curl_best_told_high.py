# The push-curl RLD seeds' best/ actors (each run's best training-time evaluation: highest ASL on the nominal
# evaluation piles, which hold no slope told wrong) on a 15 deg pile told 30, 25 and 15 deg and a 30 deg pile told
# the truth, 5 homogeneous piles (seeds 7000-7004) each: the skill the final actors lose. Run from the repository root:
#   .venv/bin/python docs/evidence/told_high_bound/push_curl_best_told_high.py > docs/evidence/told_high_bound/push_curl_best_told_high.txt
import math, sys, numpy as np
from dataclasses import replace
from lhd_loading_ros.learning import experiment as ex
from lhd_loading_ros.task.randomization import NOMINAL
import json
cfgf="docs/evidence/told_high_bound/lhd_params_steep_push_curl_nominal_eval.yaml"
dirs={f"s{s}": f"runs/push_curl_rld/seed_{s}/best" for s in range(5)}
ex._setup(cfgf, dirs); env=ex._env("rld")
for k,dd in dirs.items():
    out=[]
    for slope,told in ((15.,30.),(15.,25.),(15.,15.),(30.,30.)):
        M=[];S=0
        for ep in range(5):
            opts={"slope_deg":slope,"material":"homogeneous"}
            if told!=slope: opts["conditions"]=replace(NOMINAL, slope_error_deg=told-slope)
            obs,_=env.reset(seed=7000+ep, options=opts); t=math.radians(env.told_slope_deg)
            while True:
                a=np.clip(np.asarray(ex._actor(k)(ex.told_observation(obs,t,env.p)),dtype=np.float64),-1,1)
                obs,r,term,trunc,info=env.step(a)
                if term or trunc: res=info["episode_result"]; break
            M.append(res.loaded); S+=res.success
        out.append(f"{slope:.0f}/told {told:.0f}: {S}/5 {np.mean(M):.1f} kg")
    meta=json.load(open(dd+"/policy.json")); print(k, "best at step", meta.get("steps", meta.get("training",{}).get("steps")), " | ".join(out), flush=True)
