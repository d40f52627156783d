"""What a run's final critics say about the teacher's maneuver on a 10 deg pile (2026-12-02, thirty-fifth session;
docs/training.md "Saturated actors"). For each seed of each run: the training's teacher (the run's own demonstration
settings, crowd 0.625) drives the held-out 10 deg piles of episodes 0-5 (seed 2,000,000) and the piles it succeeds on
(four of six: 29-41 kg) are kept; at each of its states before it curls, the seed's final critic values the teacher's action (bucket still) and the same action with the bucket curling
at full rate (+1). Printed: the share of those states where the critic prefers the teacher's still bucket, the mean
difference Q(still) - Q(curl) (scaled returns). From the repository root:
    .venv/bin/python docs/evidence/preact/critic_on_teacher.py CONFIG RUN [RUN ...]"""
import sys
from pathlib import Path

import numpy as np
import torch

from lhd_loading_ros.learning.demonstrations import DemoConfig
from lhd_loading_ros.learning.evaluate import episode_conditions
from lhd_loading_ros.learning.mlp import FlatMlp
from lhd_loading_ros.learning.train import load_checkpoint
from lhd_loading_ros.task.actions import ACT_DIM
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.observation import OBS_DIM
from lhd_sim_node.env import LhdLoadingEnv

CROWD = 0.625


def teacher_states(cfg, slope=10.0, episodes=range(6)):
    env = LhdLoadingEnv("rlc", cfg, zones_from_estimate=True)
    demos = DemoConfig.from_training(cfg["training"])
    kept, results = [], []
    for k in episodes:
        seed, opts = episode_conditions(k, 2_000_000)
        obs, _ = env.reset(seed=seed, options=dict(opts, slope_deg=slope))
        rows = []
        while True:
            a = demos.action(env, CROWD)
            if a[2] <= -1.0 + 1e-9:                # the bucket still: the part of the maneuver the actor skips
                rows.append((obs.copy(), a.copy()))
            obs, _, term, trunc, info = env.step(a)
            if term or trunc:
                break
        results.append(info["episode_result"])
        if results[-1].success:
            kept += rows
    return kept, results


def main(cfg_path, runs):
    cfg = load_config(cfg_path)
    rows, results = teacher_states(cfg)
    print("the teacher on six held-out 10 deg piles: " + ", ".join(f"{r.loaded:.0f} kg {'ok' if r.success else 'failed'}"
                                                                   for r in results)
          + f"; {len(rows)} states with the bucket still on the piles it succeeds on")
    still = torch.tensor(np.array([np.concatenate([o, a]) for o, a in rows]), dtype=torch.float32)
    curl = still.clone()
    curl[:, OBS_DIM + 2] = 1.0
    for run in runs:
        for k in range(5):
            ck_path = Path(run) / f"seed_{k}" / "checkpoint.pt"
            if not ck_path.is_file():
                continue
            ck = load_checkpoint(ck_path)
            hidden = [int(h) for h in cfg["training"]["hidden_sizes"]]
            critic = FlatMlp([OBS_DIM + ACT_DIM, *hidden, 1], "identity")
            critic.flat.copy_(ck["agent"]["critic"])
            d = (critic(still) - critic(curl))[:, 0]
            print(f"{run} seed {k}: the critic prefers the teacher's still bucket on {float((d > 0).float().mean()):.0%} "
                  f"of its states, Q(still) - Q(curl) mean {float(d.mean()):+.2f}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
