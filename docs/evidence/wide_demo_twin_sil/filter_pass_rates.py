"""How often each filter would let a trained checkpoint clone the scripted demonstrations, on 11, 14 and 25 deg piles
under the training file's randomised conditions: the Q-filter (Q(o, a_demo) > Q(o, mu(o)), by the first critic) and
the return filter (reward_scale G > Q(o, mu(o)), G the demonstration's own discounted return from the row on).

    .venv/bin/python docs/evidence/wide_demo_twin_sil/filter_pass_rates.py runs/<study>/rlc_dr/seed_N/checkpoint.pt ...

Eight demonstrations a slope (the training draw of the crowd), seeds 5,000,000 + k."""
import sys, math, torch, numpy as np
torch.set_num_threads(1)
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
from lhd_loading_ros.learning.demonstrations import DemoConfig, demo_action
from lhd_sim_node.env import LhdLoadingEnv
cfgp = "docs/evidence/wide_demo_twin_mass/lhd_params_wide_demo_twin_mass.yaml"
cfg = load_config(cfgp)
dc = DdpgConfig.from_config(cfg); demos = DemoConfig.from_training(cfg["training"])
env = LhdLoadingEnv("rlc", cfg)
for ck in sys.argv[1:]:
    st = torch.load(ck, weights_only=True)
    ag = DdpgAgent(dc, 0); ag.load_state_dict(st["agent"])
    for slope in (11.0, 14.0, 25.0):
        qf = rf = n = 0; succ = 0; Gs=[]; qd=[]; qp=[]
        for k in range(8):
            rng = np.random.default_rng([k, 7])
            obs = env.reset(seed=5_000_000 + k, options={"slope_deg": slope})[0]
            crowd = float(rng.uniform(demos.crowd_min, demos.crowd_max))
            O, A, R = [], [], []
            while True:
                a = demo_action(env, crowd, demos.pre_curl)
                o2, r, term, trunc, info = env.step(a)
                O.append(obs); A.append(a); R.append(r); obs = o2
                if term or trunc: break
            succ += int(info["episode_result"].success)
            G = np.zeros(len(R)); g = 0.0
            for t in range(len(R) - 1, -1, -1):
                g = R[t] + dc.gamma * g; G[t] = g
            o = torch.tensor(np.array(O), dtype=torch.float32); a = torch.tensor(np.array(A), dtype=torch.float32)
            with torch.no_grad():
                q_demo = ag.critic(torch.cat((o, a), 1))[:, 0].numpy()
                q_pi = ag.critic(torch.cat((o, ag.actor(o)), 1))[:, 0].numpy()
            Gsc = G * dc.reward_scale
            qf += int((q_demo > q_pi).sum()); rf += int((Gsc > q_pi).sum()); n += len(R)
            Gs.append(Gsc[0]); qd.append(q_demo[0]); qp.append(q_pi[0])
        print(f"{'/'.join(ck.split('/')[-4:-1])} slope {slope}: demo success {succ}/8, rows {n}: Q-filter passes {qf/n:.2f}, "
              f"return filter {rf/n:.2f}; first step: G {np.mean(Gs):.2f} Q(o,a_demo) {np.mean(qd):.2f} Q(o,mu) {np.mean(qp):.2f}")
