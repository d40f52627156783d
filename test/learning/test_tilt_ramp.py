"""The tilt penalty ramped in once the actor loads (task.r_tilt_ramp_after_success /
r_tilt_ramp_steps): the schedule by hand, the replay relabelling every stored transition with the
weight of the moment, a short real training run that keeps the term apart, and the config hash
that the schedule never enters (actors trained with or without it run on the same config); the
pitch margin riding on the same ramp (task.r_tilt_ramp_pitch_margin)."""
PARALLEL_SAFE = True

import csv
import json

import numpy as np
import pytest
import torch

from lhd_loading_ros.learning.ddpg import ReplayBuffer, TiltRamp
from lhd_loading_ros.task.config import config_hash, validate


def test_the_ramp_by_hand():
    r = TiltRamp(after_success=0.5, steps=1000)
    assert r.enabled and r.weight(0) == 0.0
    assert r.evaluated(0.0, 10_000) is False and r.weight(15_000) == 0.0
    assert r.evaluated(0.49, 20_000) is False and r.weight(25_000) == 0.0
    assert r.evaluated(0.5, 30_000) is True and r.start_step == 30_000
    assert r.weight(30_000) == 0.0 and r.weight(30_250) == pytest.approx(0.25) and r.weight(31_000) == 1.0
    assert r.weight(300_000) == 1.0
    assert r.evaluated(1.0, 40_000) is False and r.start_step == 30_000     # starts once
    assert r.evaluated(0.0, 50_000) is False and r.weight(50_000) == 1.0    # and stays
    # off: the whole penalty throughout; steps 0: at once
    assert TiltRamp(0.0, 1000).weight(0) == 1.0 and not TiltRamp(0.0, 1000).enabled
    assert TiltRamp(0.0, 1000).evaluated(1.0, 10) is False
    at_once = TiltRamp(0.25, 0)
    at_once.evaluated(0.3, 10)
    assert at_once.weight(10) == 1.0
    # resumable; another schedule is refused
    again = TiltRamp(0.5, 1000)
    again.load_state_dict(r.state_dict())
    assert again.weight(30_250) == pytest.approx(0.25)
    with pytest.raises(ValueError, match="tilt ramp"):
        TiltRamp(0.75, 1000).load_state_dict(r.state_dict())
    for bad in ((-0.1, 10), (1.5, 10), (0.5, -1)):
        with pytest.raises(ValueError):
            TiltRamp(*bad)


def test_the_replay_relabels_every_transition_with_the_current_weight():
    rb = ReplayBuffer(4, aux=True)
    for k, (r, tilt) in enumerate([(1.0, -10.0), (2.0, 0.0), (3.0, -30.0)]):
        rb.add(np.full(12, k), np.zeros(3), r, False, np.full(12, k + 1), aux=tilt)
    gen = torch.Generator().manual_seed(0)

    def rewards_by_row(weight):
        rb.aux_weight = weight
        oa, r, nd, o2 = rb.sample(64, gen)
        assert o2.shape == (64, 12) and torch.equal(o2[:, 0], oa[:, 0] + 1)   # o' is not the aux column
        return {int(o): float(x) for o, x in zip(oa[:, 0], r[:, 0])}

    assert rewards_by_row(0.0) == {0: 1.0, 1: 2.0, 2: 3.0}
    assert rewards_by_row(0.5) == {0: -4.0, 1: 2.0, 2: -12.0}
    assert rewards_by_row(1.0) == {0: -9.0, 1: 2.0, 2: -27.0}
    # a buffer without the column refuses a term it cannot keep, and the layouts do not mix
    plain = ReplayBuffer(4)
    with pytest.raises(ValueError, match="aux"):
        plain.add(np.zeros(12), np.zeros(3), 0.0, False, np.zeros(12), aux=-1.0)
    with pytest.raises(ValueError, match="r_tilt_ramp"):
        plain.load_state_dict(rb.state_dict())


def test_the_schedule_is_not_in_the_config_hash(cfg):
    c = json.loads(json.dumps(cfg))
    c["task"]["r_tilt_per_deg"] = 10.0
    h = config_hash(c)
    c["task"]["r_tilt_ramp_after_success"], c["task"]["r_tilt_ramp_steps"] = 0.5, 12345
    assert config_hash(validate(c)) == h
    c["task"]["r_tilt_ramp_pitch_margin"] = 1
    assert config_hash(validate(c)) == h
    stripped = json.loads(json.dumps(c))
    del stripped["task"]["r_tilt_ramp_after_success"], stripped["task"]["r_tilt_ramp_steps"]
    del stripped["task"]["r_tilt_ramp_pitch_margin"]
    assert config_hash(stripped) == h          # actors trained before the keys existed keep their hash
    c["task"]["r_tilt_ramp_after_success"] = 1.5
    with pytest.raises(Exception, match="r_tilt_ramp_after_success"):
        validate(c)


def test_a_short_run_keeps_the_tilt_term_apart(cfg, tmp_path):
    """A fresh actor's evaluations do not succeed in every episode, so the weight stays 0; the
    replay's reward column plus its tilt column is the environment's reward, and summed over the
    first episode it is that episode's return in episodes.csv (written from the env's rewards)."""
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy

    cfg["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 300,
                            "checkpoint_every": 300, "hidden_sizes": [16, 16]})
    cfg["task"].update({"r_tilt_per_deg": 10.0, "r_tilt_free_deg": 0.0,      # any pitch costs: a term to see
                        "r_tilt_ramp_after_success": 1.0, "r_tilt_ramp_steps": 1000})
    out = tmp_path / "run"
    train("rld", 3, out, steps=300, config=cfg, progress=False, log=lambda *a: None)
    st = torch.load(out / "checkpoint.pt", weights_only=True)
    ramp = json.loads(st["tilt_ramp"])
    assert ramp == {"after_success": 1.0, "steps": 1000, "start_step": None}
    assert json.loads((out / "run.json").read_text())["tilt_ramp"] == ramp
    data = st["replay"]["data"].numpy().astype(np.float64)
    assert data.shape == (300, 12 + 3 + 2 + 12 + 1)
    tilt = data[:, -1]
    assert (tilt <= 0).all() and (tilt < 0).any(), tilt[:20]
    eps = list(csv.DictReader((out / "episodes.csv").open()))
    assert eps, "no episode ended in 300 steps"
    n = int(eps[0]["steps"])
    full = data[:n, 15] + data[:n, -1]
    assert full.sum() == pytest.approx(float(eps[0]["return"]), rel=1e-4, abs=1e-2)
    assert data[:n, 15].sum() > full.sum()       # the penalty is not in the stored reward
    tw = load_policy(out / "final").meta["trained_with"]
    assert tw["r_tilt_ramp_after_success"] == 1.0 and tw["r_tilt_ramp_steps"] == 1000
    # another schedule does not resume this run
    cfg["task"]["r_tilt_ramp_after_success"] = 0.5
    with pytest.raises(ValueError, match="tilt ramp"):
        train("rld", 3, out, steps=400, config=cfg, progress=False, log=lambda *a: None)
    # the sim nodes' transitions have no terms apart: refused with the reason
    with pytest.raises(ValueError, match="in-process"):
        train("rld", 3, tmp_path / "ros", steps=10, config=cfg, progress=False, env_kind="ros",
              namespaces=["/sim0"])


def test_a_ramp_that_begins_reaches_the_updates_and_the_card(cfg, tmp_path, monkeypatch):
    """The evaluation is made to report success 1.0, so the ramp begins at the first evaluation
    (step 150) and the weight at step 300 is (300 - 150) / 1000 = 0.15. The same run with the ramp
    never beginning collects identical transitions until its first update (the evaluations use
    their own environment), so its actor differs only through the weighted tilt term. The card records the
    weight, and `lhd ship`'s reading of it (ramp_progress) gives the same from run.json."""
    import lhd_loading_ros.learning.train as train_mod
    from lhd_loading_ros.learning.ship import ramp_progress
    from lhd_loading_ros.policy.actor_file import load_policy

    cfg["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 150,
                            "checkpoint_every": 150, "hidden_sizes": [16, 16]})
    cfg["task"].update({"r_tilt_per_deg": 10.0, "r_tilt_free_deg": 0.0,
                        "r_tilt_ramp_after_success": 0.5, "r_tilt_ramp_steps": 1000})
    real_evaluate = train_mod.evaluate

    def evaluate_reporting(rate):
        def ev(*a, **kw):
            out = real_evaluate(*a, **kw)
            return {**out, "success_rate": rate}
        return ev

    monkeypatch.setattr(train_mod, "evaluate", evaluate_reporting(1.0))
    logs = []
    train_mod.train("rld", 3, tmp_path / "on", steps=300, config=cfg, progress=False, log=logs.append)
    monkeypatch.setattr(train_mod, "evaluate", evaluate_reporting(0.0))
    train_mod.train("rld", 3, tmp_path / "off", steps=300, config=cfg, progress=False, log=lambda *a: None)
    assert any("ramped in over 1,000 steps" in m and "150" in m for m in logs), logs
    on = load_policy(tmp_path / "on" / "final")
    off = load_policy(tmp_path / "off" / "final")
    assert on.meta["tilt_ramp"]["start_step"] == 150 and on.meta["tilt_ramp"]["weight"] == pytest.approx(0.15)
    assert off.meta["tilt_ramp"]["start_step"] is None and off.meta["tilt_ramp"]["weight"] == 0.0
    w_on = np.load(tmp_path / "on" / "final" / "actor.npz")
    w_off = np.load(tmp_path / "off" / "final" / "actor.npz")
    assert not all(np.array_equal(w_on[k], w_off[k]) for k in w_on.files)
    # until the first update (learning_starts, 256) the two runs collected the same transitions
    # (the replays equal there, tilt column included); the actors differ through the updates alone
    r_on = torch.load(tmp_path / "on" / "checkpoint.pt", weights_only=True)["replay"]["data"]
    r_off = torch.load(tmp_path / "off" / "checkpoint.pt", weights_only=True)["replay"]["data"]
    assert torch.equal(r_on[:256], r_off[:256]) and (r_on[:256, -1] < 0).any()
    # ship's reading, from the card and from run.json alone (cards exported before the weight was)
    assert ramp_progress(tmp_path / "on", on.meta) == (150, pytest.approx(0.15))
    meta_old = {k: v for k, v in on.meta.items() if k != "tilt_ramp"}
    assert ramp_progress(tmp_path / "on", meta_old) == (150, pytest.approx(0.15))
    assert ramp_progress(tmp_path / "off", {k: v for k, v in off.meta.items() if k != "tilt_ramp"}) == (None, 0.0)


def test_a_resume_keeps_the_mass_margin(cfg, tmp_path):
    """task.r_success_mass_margin_kg is not in the config hash, so the checkpoint records it: a resume
    with another margin is refused with the key named; with the same margin it resumes."""
    from lhd_loading_ros.learning.train import train

    cfg["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 300,
                            "checkpoint_every": 300, "hidden_sizes": [16, 16]})
    cfg["task"]["r_success_mass_margin_kg"] = 4.0
    train("rld", 4, tmp_path / "r", steps=300, config=cfg, progress=False, log=lambda *a: None)
    assert torch.load(tmp_path / "r" / "checkpoint.pt", weights_only=True)["r_success_mass_margin_kg"] == 4.0
    cfg["task"]["r_success_mass_margin_kg"] = 0.0
    with pytest.raises(ValueError, match="r_success_mass_margin_kg = 4, this config has 0"):
        train("rld", 4, tmp_path / "r", steps=350, config=cfg, progress=False, log=lambda *a: None)
    # a branch may change the schedule but not the margin: the replay's r_success cuts were made with it
    cfg["task"]["r_success_mass_margin_kg"] = 8.0
    with pytest.raises(ValueError, match="this config has 8: resume or branch with the same margin"):
        train("rld", 4, tmp_path / "b", steps=350, config=cfg, progress=False, log=lambda *a: None,
              branch_from=tmp_path / "r" / "checkpoint.pt")
    cfg["task"]["r_success_mass_margin_kg"] = 4.0
    logs = []
    train("rld", 4, tmp_path / "r", steps=350, config=cfg, progress=False, log=logs.append)
    assert any("resumed" in m for m in logs), logs


def test_a_run_without_the_ramp_resumes_whatever_its_unused_steps(cfg, tmp_path):
    """r_tilt_ramp_steps means nothing while the ramp is off: changing it must not stop a resume."""
    from lhd_loading_ros.learning.train import train

    cfg["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 300,
                            "checkpoint_every": 300, "hidden_sizes": [16, 16]})
    cfg["task"].update({"r_tilt_per_deg": 10.0, "r_tilt_ramp_after_success": 0.0, "r_tilt_ramp_steps": 1000})
    train("rld", 4, tmp_path / "r", steps=300, config=cfg, progress=False, log=lambda *a: None)
    cfg["task"]["r_tilt_ramp_steps"] = 5000
    logs = []
    train("rld", 4, tmp_path / "r", steps=350, config=cfg, progress=False, log=logs.append)
    assert any("resumed" in m for m in logs), logs


def test_the_margin_cut_by_hand(cfg):
    """r_success_margin_cut: zero outside the margin, the whole r_success inside it (the paper's
    test passes, the margin's fails), r_success = R_success (d_w + d_p) / 2 max(W, W_target)."""
    import math
    from dataclasses import replace

    from lhd_loading_ros.task.params import TaskParams
    from lhd_loading_ros.task.reward import r_success, r_success_margin_cut

    p = replace(TaskParams.from_config(cfg), r_success_pitch_margin=math.radians(3.0))
    W = 30.0
    inside, above, below = math.radians(41.5), math.radians(45.0), math.radians(39.0)
    assert r_success_margin_cut(W, above, p) == 0.0 and r_success_margin_cut(W, below, p) == 0.0
    assert r_success(W, inside, p) == 0.0
    full = r_success(W, inside, replace(p, r_success_pitch_margin=0.0))
    assert full > 0 and r_success_margin_cut(W, inside, p) == -full
    assert r_success_margin_cut(W, inside, replace(p, r_success_pitch_margin=0.0)) == 0.0


def test_the_mass_margin_s_cut_by_hand(cfg):
    """r_success_margin_cut with task.r_success_mass_margin_kg: zero at or above 20 kg + margin and
    below 20 kg (the paper's test fails too), the whole of the paper's r_success for a load within
    the margin, so that a ramped margin (r_tilt_ramp_pitch_margin) cuts exactly that."""
    import math
    from dataclasses import replace

    from lhd_loading_ros.task.params import TaskParams
    from lhd_loading_ros.task.reward import r_success, r_success_margin_cut

    p = replace(TaskParams.from_config(cfg), r_success_pitch_margin=0.0, r_success_mass_margin=4.0)
    phi = math.radians(45.0)
    assert r_success_margin_cut(24.0, phi, p) == 0.0 and r_success_margin_cut(30.0, phi, p) == 0.0
    assert r_success_margin_cut(19.9, phi, p) == 0.0
    for W in (20.0, 22.0, 23.99):
        full = r_success(W, phi, replace(p, r_success_mass_margin=0.0))
        assert full > 0 and r_success(W, phi, p) == 0.0 and r_success_margin_cut(W, phi, p) == -full
    # with the pitch margin as well, a load inside the mass margin at a pitch inside the pitch
    # margin loses the same whole r_success, once
    both = replace(p, r_success_pitch_margin=math.radians(3.0))
    inside = math.radians(41.5)
    assert r_success_margin_cut(22.0, inside, both) == -r_success(22.0, inside, replace(both, r_success_pitch_margin=0.0,
                                                                                         r_success_mass_margin=0.0))


def test_a_ramped_mass_margin_alone_is_accepted_and_no_margin_is_refused(cfg, tmp_path):
    """r_tilt_ramp_pitch_margin = 1 needs a margin to ramp: the mass margin alone is one; with neither
    margin training refuses to start and names the keys."""
    import copy

    from lhd_loading_ros.learning.train import train

    base = copy.deepcopy(cfg)
    base["task"].update(r_tilt_per_deg=10.0, r_tilt_ramp_after_success=0.5, r_tilt_ramp_steps=5000,
                        r_tilt_ramp_pitch_margin=1, r_success_pitch_margin_deg=0.0, r_success_mass_margin_kg=0.0)
    with pytest.raises(ValueError, match="r_success_mass_margin_kg"):
        train("rld", 0, tmp_path / "none", steps=10, config=base, progress=False, log=lambda m: None)
    mass = copy.deepcopy(base)
    mass["task"]["r_success_mass_margin_kg"] = 4.0
    train("rld", 0, tmp_path / "mass", steps=30, config=mass, progress=False, log=lambda m: None)
    card = json.loads((tmp_path / "mass" / "final" / "policy.json").read_text())
    assert card["trained_with"]["r_success_mass_margin_kg"] == 4.0


def test_a_ramped_margin_pays_r_success_at_40_deg_until_the_ramp(cfg, tmp_path, monkeypatch):
    """task.r_tilt_ramp_pitch_margin = 1: the env's success_margin_cut goes into the aux column
    with the tilt term, so the stored reward is the paper's r_success (no margin) until the ramp
    weights the cut in. The env is made to end every episode as a success just inside the margin
    (41 deg), so every terminal transition carries a cut; the stored columns add up to the env's
    reward. Without the ramp on, the setting is refused with the reason."""
    import math

    import lhd_loading_ros.task.reward as reward_mod
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy

    cfg["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 300,
                            "checkpoint_every": 300, "hidden_sizes": [16, 16]})
    cfg["task"].update({"r_tilt_per_deg": 10.0, "r_tilt_free_deg": 0.0, "r_success_pitch_margin_deg": 3.0,
                        "r_tilt_ramp_after_success": 1.0, "r_tilt_ramp_steps": 1000, "r_tilt_ramp_pitch_margin": 1})
    real_step = reward_mod.RewardTracker.step
    seen = []

    def step_success_inside_margin(self, s, *a, **kw):
        from dataclasses import replace as rep
        a = list(a)
        if len(seen) % 7 == 6:      # every 7th transition: a success at 41 deg, 30 kg
            s = rep(s, phi_shovel=math.radians(41.0))
            a[2] = 30.0                                     # W
            a[5] = "success"                                # outcome
        seen.append(1)
        return real_step(self, s, *a, **kw)

    monkeypatch.setattr(reward_mod.RewardTracker, "step", step_success_inside_margin)
    out = tmp_path / "run"
    train("rld", 5, out, steps=300, config=cfg, progress=False, log=lambda *x: None)
    st = torch.load(out / "checkpoint.pt", weights_only=True)
    assert json.loads(st["tilt_ramp"])["pitch_margin"] is True
    data = st["replay"]["data"].numpy().astype(np.float64)
    aux = data[:, -1]
    # a terminal success inside the margin: the aux column holds minus the whole r_success
    # (hundreds to thousands), far beyond a step's tilt term
    assert (aux < -100).any(), aux.min()
    eps = list(csv.DictReader((out / "episodes.csv").open()))
    n = int(eps[0]["steps"])
    assert data[:n, 15].sum() + aux[:n].sum() == pytest.approx(float(eps[0]["return"]), rel=1e-4, abs=1e-2)
    assert load_policy(out / "final").meta["trained_with"]["r_tilt_ramp_pitch_margin"] == 1
    cfg["task"]["r_tilt_ramp_after_success"] = 0.0
    with pytest.raises(ValueError, match="r_tilt_ramp_pitch_margin"):
        train("rld", 5, tmp_path / "bad", steps=10, config=cfg, progress=False, log=lambda *x: None)
