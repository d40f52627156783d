# What the push-curl RLD actors (seeds 0, 2) and the teacher see and do, by the tip x (0.05 m bins), on 15, 25,
# 30 and 35 deg piles all told 30 deg: mean v_x (m/s), the drift flag, the action (wheels, boom, bucket; boom +1 is
# still, -1 lifts at full rate; bucket -1 still, +1 curls at full rate). 3 homogeneous piles each. Run:
#   .venv/bin/python docs/evidence/told_high_bound/told_high_what_they_see.py > docs/evidence/told_high_bound/told_high_what_they_see.txt
import math, numpy as np
from dataclasses import replace
from lhd_loading_ros.learning import experiment as ex
from lhd_loading_ros.task.randomization import NOMINAL
from lhd_loading_ros.learning.demonstrations import demo_action
cfg="docs/evidence/told_high_bound/lhd_params_steep_push_curl_nominal_eval.yaml"
ex._setup(cfg, {f"s{s}": f"runs/push_curl_rld/seed_{s}/final" for s in range(5)})
env=ex._env("rld")
for ctl in ("s0","s2","teacher"):
  for slope,told in ((15.,30.),(30.,30.),(25.,30.),(35.,30.)):
    bins={}
    for ep in range(3):
        opts={"slope_deg":slope,"material":"homogeneous"}
        if told!=slope: opts["conditions"]=replace(NOMINAL, slope_error_deg=told-slope)
        obs,_=env.reset(seed=7000+ep, options=opts); t=math.radians(env.told_slope_deg)
        teacher=ex.teacher_setting(env.cfg)
        while True:
            o=ex.told_observation(obs,t,env.p)
            a=demo_action(env,*teacher,measured=True) if ctl=="teacher" else np.clip(np.asarray(ex._actor(ctl)(o),dtype=np.float64),-1,1)
            x=env.state.x_shovel; b=round(x*20)/20
            if 0.3<=b<=0.8: bins.setdefault(b,[]).append((env.state.v_x, env.state.drift, a[0], a[1], a[2]))
            obs,r,term,trunc,info=env.step(a)
            if term or trunc: break
    print(ctl, f"pile {slope:.0f} told {told:.0f}:", "  ".join(f"{b:.2f}: v {np.mean([q[0] for q in v]):.2f} dr {np.mean([q[1] for q in v]):.1f} a {np.mean([q[2] for q in v]):+.1f},{np.mean([q[3] for q in v]):+.1f},{np.mean([q[4] for q in v]):+.1f}" for b,v in sorted(bins.items())))
