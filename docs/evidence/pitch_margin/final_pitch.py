# Final bucket pitch of end-zone arrivals, 60 held-out episodes (seed 2,000,000) per actor:
# .venv/bin/python docs/evidence/pitch_margin/final_pitch.py ACTOR_DIR ...  (output: final_pitch.txt)
import sys, math, numpy as np
from lhd_loading_ros.learning.evaluate import episode_conditions, run_policy_episode
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_sim_node.env import LhdLoadingEnv
cfg = load_config()
for d in sys.argv[1:]:
    pol = load_policy(d)
    env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=(pol.variant == "rlc"))
    rs = [run_policy_episode(env, pol.actor, *episode_conditions(i, 2_000_000)) for i in range(60)]
    ez = [r for r in rs if r.reached_end_zone]
    ph = np.array([math.degrees(r.phi_final) for r in ez])
    succ = np.mean([r.success for r in rs])
    print(f"{d}: success {succ:.3f} end-zone {len(ez)}/60 phi_final mean {ph.mean():.2f} min {ph.min():.2f} p10 {np.percentile(ph,10):.2f} <42: {np.mean(ph<42):.2f} mass {np.mean([r.loaded for r in ez]):.1f}", flush=True)
