"""How saturated the actors' output tanh is on the piles they load (2026-12-02, thirty-fifth session; docs/training.md
"Saturated actors"). For each actor directory (RLC with the deployment filter, RLD with its hybrid filter, as the nodes
run them), 8 held-out episodes a slope of 10 / 15 / 20 / 30 / 40 deg (seeds 2,000,000 + k, the evaluation file of the
10-40 deg RLCs): per output, the share of control steps whose tanh input |z| exceeds 3 (tanh' < 0.01) and 5
(tanh' < 1.8e-4), and the median |z|. With CRITIC=RUN/seed_K in the environment, also the run's final critic along
that seed's final actor's path on a 10 deg pile: Q(o, a) with the bucket action replaced by -1 / 0 / +1, the
actor's own value, and the bucket's z. From the repository root:
    .venv/bin/python docs/evidence/preact/saturation.py policies/rld_drift_confirm_margin8 runs/RUN/seed_{0..4}/final
    CRITIC=runs/RUN/seed_2 .venv/bin/python docs/evidence/preact/saturation.py"""
import os
import sys
from pathlib import Path

import numpy as np

from lhd_loading_ros.learning.evaluate import episode_conditions
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import load_config
from lhd_sim_node.env import LhdLoadingEnv

CFG = "docs/evidence/steep_piles/lhd_params_steep_rlc_nominal_eval.yaml"
SLOPES = (10.0, 15.0, 20.0, 30.0, 40.0)
EPISODES = 8


def preactivation(actor, obs) -> np.ndarray:
    h = np.asarray(obs, dtype=np.float32)
    for j, (W, b) in enumerate(actor.layers):
        h = W @ h + b
        if j < len(actor.layers) - 1:
            h = np.maximum(h, 0.0)
    return h


def variant_of(d: str) -> str:
    return load_policy(d).meta.get("variant", "rlc")


def saturation(cfg, d: str) -> str:
    v = variant_of(d)
    env = LhdLoadingEnv(v, cfg, deploy_filter=(v == "rlc"), zones_from_estimate=True)
    actor = load_policy(d).actor
    zs, ok, n = [], 0, 0
    for slope in SLOPES:
        for k in range(EPISODES):
            seed, opts = episode_conditions(k, 2_000_000)
            obs, _ = env.reset(seed=seed, options=dict(opts, slope_deg=slope))
            while True:
                zs.append(preactivation(actor, obs))
                obs, _, term, trunc, info = env.step(np.clip(actor(obs), -1.0, 1.0))
                if term or trunc:
                    ok += int(info["episode_result"].success)
                    n += 1
                    break
    z = np.abs(np.array(zs))
    cols = [f"{name} |z|>3 {np.mean(z[:, i] > 3):4.0%} >5 {np.mean(z[:, i] > 5):4.0%} median {np.median(z[:, i]):5.1f}"
            for i, name in enumerate(("wheels", "boom", "bucket"))]
    return f"{d} ({v}, {len(z)} steps, success {ok}/{n})\n    " + "\n    ".join(cols)


def critic_along_path(cfg, seed_dir: Path) -> None:
    import torch
    from lhd_loading_ros.learning.mlp import FlatMlp
    from lhd_loading_ros.learning.train import load_checkpoint
    pol = load_policy(seed_dir / "final")
    actor = pol.actor
    ck = load_checkpoint(seed_dir / "checkpoint.pt")
    critic = FlatMlp([actor.obs_dim + actor.act_dim, *actor.sizes[1:-1], 1], "identity")
    critic.flat.copy_(ck["agent"]["critic"])
    env = LhdLoadingEnv("rlc", cfg, deploy_filter=True, zones_from_estimate=True)
    seed, opts = episode_conditions(0, 2_000_000)
    obs, _ = env.reset(seed=seed, options=dict(opts, slope_deg=10.0))
    print(f"{seed_dir}: its final critic along its final actor's path on a 10 deg pile (held-out seed 2,000,000)")
    print("   x (m)  a_bucket  z_bucket  Q(actor)  Q(bucket -1)  Q(0)   Q(+1)")
    k = 0
    while True:
        a = np.clip(actor(obs), -1.0, 1.0)
        if k % 2 == 0:
            rows = [np.concatenate([obs, a])] + [np.concatenate([obs, a[:2], [b]]) for b in (-1.0, 0.0, 1.0)]
            q = critic(torch.tensor(np.array(rows), dtype=torch.float32))[:, 0].tolist()
            print(f"  {env.state.x_shovel:6.3f}  {a[2]:+6.2f}  {preactivation(actor, obs)[2]:+7.2f}  {q[0]:8.2f}  "
                  f"{q[1]:8.2f}  {q[2]:8.2f}  {q[3]:8.2f}")
        obs, _, term, trunc, info = env.step(a)
        k += 1
        if term or trunc:
            r = info["episode_result"]
            print(f"  loaded {r.loaded:.1f} kg, {'success' if r.success else 'failure'}")
            return


def main(dirs):
    cfg = load_config(CFG)
    if os.environ.get("CRITIC"):
        critic_along_path(cfg, Path(os.environ["CRITIC"]))
    for d in dirs:
        print(saturation(cfg, d))


if __name__ == "__main__":
    main(sys.argv[1:])
