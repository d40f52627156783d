"""Training does not end on a stalled attack drive (AttackError at reset): the episode's pile and
conditions are drawn again, deterministically, at the same slope. The real case: a randomised
35 deg pile (slow attack, a stone at the toe) whose attack stalls 1 mm short of d_init."""
import copy

import numpy as np
import pytest

from lhd_sim_node.env import ATTACK_REDRAWS, LhdLoadingEnv, reset_or_redraw
from lhd_sim_node.simulator import AttackError


@pytest.fixture(scope="module")
def steep_env():
    from lhd_loading_ros.task.config import load_config
    cfg = copy.deepcopy(load_config())
    cfg["paper"]["episode"]["alpha_min_deg"], cfg["paper"]["episode"]["alpha_max_deg"] = 10.0, 35.0
    return LhdLoadingEnv("rld", cfg, randomize=True)


def test_a_stalled_attack_is_redrawn_at_the_same_slope(steep_env):
    steep_env.attack_redraws = 0                      # the env's own redraws off: this seed's attack stalls
    with pytest.raises(AttackError, match="did not reach d_init"):
        steep_env.reset(seed=14, options={"slope_deg": 35.0})
    steep_env.attack_redraws = ATTACK_REDRAWS         # on (the default): reset() itself draws again
    _, info = steep_env.reset(seed=14, options={"slope_deg": 35.0})
    assert info["attack_redraws"] >= 1 and abs(np.degrees(steep_env.sim.pile.alpha) - 35.0) < 1e-9
    lines = []
    obs = reset_or_redraw(steep_env, 14, {"slope_deg": 35.0}, lines.append)
    assert obs.shape == (12,) and np.isfinite(obs).all()
    assert abs(np.degrees(steep_env.sim.pile.alpha) - 35.0) < 1e-9        # the curriculum's slope is kept
    assert len(lines) == 1 and "drawn again (1 redraw)" in lines[0]
    first = steep_env.sim.state()
    # deterministic: the same redraw again (a resumed run replays it)
    reset_or_redraw(steep_env, 14, {"slope_deg": 35.0}, lambda *_: None)
    assert steep_env.sim.state() == first


def test_a_sound_reset_is_untouched_and_endless_stalls_still_raise(steep_env, monkeypatch):
    lines = []
    o1 = reset_or_redraw(steep_env, 3, {"slope_deg": 20.0}, lines.append)
    o2, _ = steep_env.reset(seed=3, options={"slope_deg": 20.0})
    assert lines == [] and np.array_equal(o1, o2)

    calls = []

    def always_stalls(*a, **k):
        calls.append(k.get("seed"))
        raise AttackError("the bucket did not reach d_init (test)")
    monkeypatch.setattr(steep_env, "reset", always_stalls)
    with pytest.raises(AttackError, match="test"):
        reset_or_redraw(steep_env, 3, {}, lines.append)
    assert len(calls) == 1 + ATTACK_REDRAWS and len(set(calls)) == len(calls)
