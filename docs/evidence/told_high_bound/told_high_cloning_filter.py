# Does the cloning filter (training.demo_bc_return_filter) keep the push-curl teacher where it is told too steep?
# For 3 piles a case, the teacher drives; each row its own discounted return to the end (x reward_scale) against
# Q(o, mu(o)) of each push-curl RLD seed's final critic (runs/push_curl_rld/seed_N/checkpoint.pt): the share of
# rows where the teacher beats the actor (the rows the actor is cloned on), with the reward of the told zones (as
# trained) and with the reward of the pile's own zones. Run from the repository root:
#   .venv/bin/python docs/evidence/told_high_bound/told_high_cloning_filter.py > docs/evidence/told_high_bound/told_high_cloning_filter.txt
import math, sys, numpy as np, torch
from dataclasses import replace
from lhd_loading_ros.learning import experiment as ex
from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.randomization import NOMINAL
from lhd_loading_ros.task.reward import RewardTracker
from lhd_loading_ros.learning.demonstrations import demo_action
cfgf="docs/evidence/told_high_bound/lhd_params_steep_push_curl_nominal_eval.yaml"
cfg=load_config(cfgf); dc=DdpgConfig.from_config(cfg)
ex._setup(cfgf, {})
env=ex._env("rld")
agents=[]
for s in range(5):
    ag=DdpgAgent(dc, 0); ag.load_state_dict(torch.load(f"runs/push_curl_rld/seed_{s}/checkpoint.pt",weights_only=True)["agent"]); agents.append(ag)
g=dc.gamma
for slope,told in ((15.,15.),(15.,25.),(15.,30.),(30.,30.),(20.,30.)):
    rows=[]
    for ep in range(3):
        opts={"slope_deg":slope,"material":"homogeneous"}
        if told!=slope: opts["conditions"]=replace(NOMINAL, slope_error_deg=told-slope)
        obs,_=env.reset(seed=7000+ep, options=opts); t=math.radians(env.told_slope_deg)
        teacher=ex.teacher_setting(env.cfg)
        pile_tr=RewardTracker(env.p.for_pile(env.sim.zones), env.sim.zones, env.p.h_pile); pile_tr.reset(env.sim.state(), env.sim.loaded_mass)
        O=[];R=[];RP=[]
        while True:
            o=ex.told_observation(obs,t,env.p); a=demo_action(env,*teacher,measured=True)
            O.append(o)
            obs,r,term,trunc,info=env.step(a)
            s=env.sim.state(); pile=env.sim.pile
            inside = 0.0 <= s.x_shovel < pile.L and s.z_shovel < pile.surface_height(s.x_shovel)
            u=info["command"]
            rp=sum(pile_tr.step(s,u[1],u[2],env.sim.loaded_mass,inside,pile.surface_height(s.x_bottom),info["outcome"],env.sim.machine_pitch()).values())
            R.append(r); RP.append(rp)
            if term or trunc: res=info["episode_result"]; break
        G=np.zeros(len(R)); GP=np.zeros(len(R)); acc=0; accp=0
        for i in range(len(R)-1,-1,-1):
            acc=R[i]+g*acc; accp=RP[i]+g*accp; G[i]=acc; GP[i]=accp
        O=torch.tensor(np.array(O))
        qs=[]
        with torch.no_grad():
            for ag in agents:
                pi=ag.actor(O); qs.append(ag.critic(torch.cat((O,pi),1)).numpy().ravel())
        rows.append((G*dc.reward_scale, GP*dc.reward_scale, np.array(qs), res.loaded, sum(R), sum(RP)))
    Gs=np.concatenate([r[0] for r in rows]); GPs=np.concatenate([r[1] for r in rows]); Q=np.concatenate([r[2] for r in rows],axis=1)
    passed=[(Gs>Q[k]).mean() for k in range(5)]; passedp=[(GPs>Q[k]).mean() for k in range(5)]
    print(f"pile {slope:.0f} told {told:.0f}: teacher load {np.mean([r[3] for r in rows]):.1f} kg, return told zones {np.mean([r[4] for r in rows]):.0f}, pile zones {np.mean([r[5] for r in rows]):.0f}; "
          f"rows passing the return filter per seed (told-zone G) {' '.join(f'{p:.2f}' for p in passed)}; with pile-zone G {' '.join(f'{p:.2f}' for p in passedp)}; "
          f"mean 0.01G {Gs.mean():.2f} vs mean Q(o,mu) {Q.mean():.2f}", flush=True)
