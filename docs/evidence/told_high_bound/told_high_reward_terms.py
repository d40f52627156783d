# Per-term return of the push-curl teacher and three push-curl RLD seeds (runs/push_curl_rld, final actors) on a
# 15 deg pile told the truth, a 15 deg pile told 30 deg and a 30 deg pile told the truth: 4 homogeneous piles
# (seeds 7000-7003) each, the zones built from the told slope as in training. Run from the repository root:
#   .venv/bin/python docs/evidence/told_high_bound/told_high_reward_terms.py > docs/evidence/told_high_bound/told_high_reward_terms.txt
import math, numpy as np, collections
from dataclasses import replace
from lhd_loading_ros.learning import experiment as ex
from lhd_loading_ros.task.randomization import NOMINAL
from lhd_loading_ros.learning.demonstrations import demo_action
cfg="docs/evidence/told_high_bound/lhd_params_steep_push_curl_nominal_eval.yaml"
ex._setup(cfg, {f"s{s}": f"runs/push_curl_rld/seed_{s}/final" for s in range(5)})
env=ex._env("rld")
for slope, told in ((15.0,15.0),(15.0,30.0),(30.0,30.0)):
    for ctl in ["teacher","s0","s2","s3"]:
        T=collections.Counter(); M=[]; S=0; R=[]
        for ep in range(4):
            opts={"slope_deg":slope,"material":"homogeneous"}
            if told!=slope: opts["conditions"]=replace(NOMINAL, slope_error_deg=told-slope)
            obs,_=env.reset(seed=7000+ep, options=opts); t=math.radians(env.told_slope_deg)
            if ctl=="teacher": teacher=ex.teacher_setting(env.cfg)
            while True:
                a=demo_action(env,*teacher,measured=True) if ctl=="teacher" else np.clip(np.asarray(ex._actor(ctl)(ex.told_observation(obs,t,env.p)),dtype=np.float64),-1,1)
                obs,r,term,trunc,info=env.step(a)
                for k,v in info["terms"].items(): T[k]+=v
                if term or trunc: res=info["episode_result"]; break
            M.append(res.loaded); S+=res.success; R.append(res.ret)
        print(f"pile {slope:.0f} told {told:.0f} {ctl:8s} ret {np.mean(R):8.1f} load {np.mean(M):5.1f} succ {S}/4  "+" ".join(f"{k}:{v/4:.0f}" for k,v in T.items() if abs(v)>1e-9), flush=True)
