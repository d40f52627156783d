# Where the five push-curl RLD seeds (runs/push_curl_rld, final actors) push and lift on a 15 deg pile told the
# truth and told 30 deg, beside the push-curl teacher: 5 homogeneous piles (seeds 7000-7004) each. 'wheels before
# the lift': the mean normalised wheel command (-1: stopped, 1: full) while the tip is past 0.4 m and the boom has
# not started to lift; 'lift at x': the tip's x where the boom first rose 1 deg. Run from the repository root:
#   .venv/bin/python docs/evidence/told_high_bound/push_curl_actors_push.py > docs/evidence/told_high_bound/push_curl_actors_push.txt
# Another run: push_curl_actors_push.py RUNS_DIR EVAL_CONFIG SEEDS (e.g. runs/told_high_demos_rld
#   docs/evidence/told_high_bound/lhd_params_steep_push_curl_nominal_eval.yaml 0,1).
import math, sys, numpy as np
from dataclasses import replace
from lhd_loading_ros.learning import experiment as ex
from lhd_loading_ros.task.randomization import NOMINAL
from lhd_loading_ros.learning.demonstrations import demo_action
runs, cfg, seeds = (sys.argv[1], sys.argv[2], [int(s) for s in sys.argv[3].split(",")]) if len(sys.argv) > 1 else \
    ("runs/push_curl_rld", "docs/evidence/told_high_bound/lhd_params_steep_push_curl_nominal_eval.yaml", list(range(5)))
ex._setup(cfg, {f"s{s}": f"{runs}/seed_{s}/final" for s in seeds})
env=ex._env("rld")
for told in (15.0, 30.0):
    for ctl in ["teacher"]+[f"s{s}" for s in seeds]:
        W=[]; X=[]; M=[]; S=0
        for ep in range(5):
            opts={"slope_deg":15.0,"material":"homogeneous"}
            if told!=15.0: opts["conditions"]=replace(NOMINAL, slope_error_deg=told-15.0)
            obs,_=env.reset(seed=7000+ep, options=opts); t=math.radians(env.told_slope_deg)
            if ctl=="teacher": teacher=ex.teacher_setting(env.cfg)
            w=[]; xl=None; b0=env.state.phi_boom
            while True:
                a=demo_action(env,*teacher,measured=True) if ctl=="teacher" else np.clip(np.asarray(ex._actor(ctl)(ex.told_observation(obs,t,env.p)),dtype=np.float64),-1,1)
                s=env.state
                if xl is None and s.phi_boom < b0-math.radians(1.0): xl=s.x_shovel
                if xl is None and s.x_shovel>0.4: w.append(a[0])
                obs,_,term,trunc,info=env.step(a)
                if term or trunc: r=info["episode_result"]; break
            W.append(np.mean(w) if w else np.nan); X.append(xl if xl is not None else np.nan); M.append(r.loaded); S+=r.success
        print(f"told {told:.0f} {ctl:8s} wheels before the lift {np.nanmean(W):.2f}  lift at x {np.nanmean(X):.2f} m  load {np.mean(M):.1f} kg  success {S}/5")
