"""The late learning-rate decay (training.lr_final_scale / lr_decay_from; learning/ddpg.py
lr_scale): the schedule by hand, the optimisers' step size under it (one Adam step measured on
the real networks), a short real run that applies it at every update, its card and the config
hash it never enters."""
PARALLEL_SAFE = True

import copy

import pytest
import torch

from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig, lr_scale
from lhd_loading_ros.task.config import config_hash, validate


def test_the_schedule_by_hand():
    # constant up to the start, linear to the final share at the end, constant after
    assert lr_scale(0, 100, 300, 0.1) == 1.0
    assert lr_scale(100, 100, 300, 0.1) == 1.0
    assert lr_scale(200, 100, 300, 0.1) == pytest.approx(1.0 - 0.9 * 0.5)     # halfway: 0.55
    assert lr_scale(250, 100, 300, 0.1) == pytest.approx(0.325)
    assert lr_scale(300, 100, 300, 0.1) == pytest.approx(0.1)
    assert lr_scale(10_000, 100, 300, 0.1) == pytest.approx(0.1)
    assert lr_scale(250, 100, 300, 1.0) == 1.0                                  # the paper: constant
    assert lr_scale(5, 300, 300, 0.2) == 1.0 and lr_scale(400, 300, 300, 0.2) == 0.2


def test_the_optimisers_step_at_the_scaled_rate(cfg):
    """Adam's first step moves every parameter by lr (m / sqrt(v) = sign(g) after bias
    correction): after set_lr_scale(0.25) the largest change of the actor is 0.25 x actor_lr."""
    c = copy.deepcopy(cfg)
    agent = DdpgAgent(DdpgConfig.from_config(c), seed=0)
    agent.set_lr_scale(0.25)
    assert agent.actor_opt.lr == pytest.approx(0.25 * c["paper"]["ddpg"]["actor_lr"])
    assert agent.critic_opt.lr == pytest.approx(0.25 * c["paper"]["ddpg"]["critic_lr"])
    before = agent.actor.flat.clone()
    agent.actor.grad.copy_(torch.linspace(-1.0, 1.0, agent.actor.grad.numel()) + 0.001)
    agent.actor_opt.step()
    step = (agent.actor.flat - before).abs().max().item()
    assert step == pytest.approx(0.25 * c["paper"]["ddpg"]["actor_lr"], rel=1e-3)


def small(cfg, final=0.2, start=300):
    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 300, "checkpoint_every": 300,
                          "hidden_sizes": [32, 32], "lr_final_scale": final, "lr_decay_from": start})
    return c


def test_a_short_run_applies_it_at_every_update(cfg, tmp_path, monkeypatch):
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy

    seen = []
    orig = DdpgAgent.set_lr_scale

    def record(self, scale):
        seen.append(scale)
        orig(self, scale)
        assert self.actor_opt.lr == pytest.approx(self.cfg.actor_lr * scale)

    monkeypatch.setattr(DdpgAgent, "set_lr_scale", record)
    c = small(cfg)
    out = tmp_path / "run"
    train("rld", 3, out, steps=700, config=c, progress=False, log=lambda *a: None)
    # one call per update, from learning_starts (256) to 700: the scale 1 until step 300, then
    # falling to 0.2 x ... at step 700 (the end of this run's schedule)
    assert len(seen) == 700 - 256 + 1
    assert seen[0] == 1.0 and seen[300 - 256] == 1.0
    assert seen[-1] == pytest.approx(lr_scale(700, 300, 700, 0.2)) == pytest.approx(0.2)
    assert all(a >= b for a, b in zip(seen, seen[1:]))               # never rises
    meta = load_policy(out / "final").meta
    assert meta["trained_with"]["lr_final_scale"] == 0.2 and meta["trained_with"]["lr_decay_from"] == 300
    # off (the paper): no call, nothing on the card
    seen.clear()
    train("rld", 3, tmp_path / "off", steps=400, config=small(cfg, final=1.0), progress=False, log=lambda *a: None)
    assert seen == [] and "lr_final_scale" not in load_policy(tmp_path / "off" / "final").meta["trained_with"]


def test_never_in_the_config_hash_and_validated(cfg):
    on = copy.deepcopy(cfg)
    on["training"].update({"lr_final_scale": 0.1, "lr_decay_from": 150_000})
    assert config_hash(validate(on)) == config_hash(cfg)
    bad = small(cfg, final=0.0)
    with pytest.raises(ValueError, match="lr_final_scale"):
        validate(bad)


def test_a_decay_that_never_starts_or_a_resume_that_moves_it_is_refused(cfg, tmp_path):
    """lr_decay_from at or past the last step would record a decay on the card that never ran; a
    resume with more steps than the decay was planned for would lift the rates again mid-run."""
    from lhd_loading_ros.learning.train import train

    with pytest.raises(ValueError, match="lr_decay_from = 300 is not before the run's last step"):
        train("rld", 3, tmp_path / "never", steps=300, config=small(cfg), progress=False, log=lambda *a: None)
    out = tmp_path / "run"
    train("rld", 3, out, steps=500, config=small(cfg), progress=False, log=lambda *a: None)
    with pytest.raises(ValueError, match="runs to step 500"):
        train("rld", 3, out, steps=800, config=small(cfg), progress=False, log=lambda *a: None)
