"""Training does not end when MuJoCo finds a state unstable (SimulationError): the step gives no
transition, the episode is written to episodes.csv as `aborted`, and the run goes on to its last
step. The fault is real: a NaN put into the training environment's MuJoCo velocities before one
step, which mj_step detects and resets as it would a diverging state (as in
test/sim/test_sim_node_abort.py)."""
PARALLEL_SAFE = True

import copy
import csv
import math

import pytest
import torch


def test_an_unstable_step_aborts_the_episode_not_the_run(cfg, tmp_path, monkeypatch):
    from lhd_loading_ros.learning.train import train
    from lhd_sim_node.env import LhdLoadingEnv

    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 64, "eval_episodes": 1, "eval_every": 150, "checkpoint_every": 150,
                          "hidden_sizes": [16, 16]})
    calls = {"n": 0, "poisoned": None}
    real_step = LhdLoadingEnv.step

    def step(self, action):
        calls["n"] += 1
        if calls["n"] == 40 and self.steps > 0:          # the training env, mid-episode (evaluations start later)
            calls["poisoned"] = self.steps
            self.sim.data.qvel[0] = math.nan
        return real_step(self, action)

    monkeypatch.setattr(LhdLoadingEnv, "step", step)
    lines = []
    train("rld", 0, tmp_path, steps=150, config=c, resume=False, progress=False, log=lines.append)
    assert calls["poisoned"] is not None
    with open(tmp_path / "episodes.csv") as f:
        rows = list(csv.DictReader(f))
    aborted = [r for r in rows if r["outcome"] == "aborted"]
    assert len(aborted) == 1
    assert int(aborted[0]["steps"]) == calls["poisoned"] and int(aborted[0]["step"]) == 39
    assert any("aborted" in ln and "unstable" in ln for ln in lines)
    # the run reached its last step: 150 transitions, none from the aborted step, all finite
    st = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    assert st["step"] == 150 and st["replay"]["size"] == 150
    assert torch.isfinite(st["replay"]["data"]).all()
    assert [int(r["episode"]) for r in rows] == sorted(int(r["episode"]) for r in rows)
