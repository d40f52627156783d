"""The environment as RL tooling uses it (an RL-API review, 2026-11-29): copies and pickles that continue bit for
bit and leave the original alone, a failed reset that leaves nothing steppable, the attack drive's stall drawn
again inside reset(), and the constructor and reset options checked with messages that name what is expected."""
import copy
import gc
import pickle

import numpy as np
import pytest

from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.simulator import AttackError

PARALLEL_SAFE = True
PUSH = np.array([1.0, -1.0, -1.0], dtype=np.float32)


def actions(n=120, seed=0):
    rng = np.random.default_rng(seed)
    return [np.clip(rng.normal(0.5, 0.5, 3), -1, 1).astype(np.float32) for _ in range(n)]


def run(env, acts):
    out = []
    for a in acts:
        o, r, te, tr, _ = env.step(a)
        out.append((o.copy(), r))
        if te or tr:
            break
    return out


def started(cfg, seed=3, steps=8):
    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=seed)
    for _ in range(steps):
        env.step(PUSH)
    return env


def same(a, b):
    return len(a) == len(b) and all(np.array_equal(x[0], y[0]) and x[1] == y[1] for x, y in zip(a, b))


def test_a_deep_copy_mid_episode_continues_bit_for_bit_and_leaves_the_original_alone(cfg):
    env, twin = started(cfg), started(cfg)            # twin: never copied, the reference continuation
    t0 = env.sim.data.time
    cp = copy.deepcopy(env)
    acts = actions()
    from_copy = run(cp, acts)
    assert env.sim.data.time == t0                   # the copy stepped its own physics, not the original's
    assert same(from_copy, run(twin, acts)) and same(from_copy, run(env, acts))
    assert len(from_copy) > 5


def test_a_pickled_env_outlives_its_original(cfg):
    env = started(cfg)
    blob = pickle.dumps(env)
    ref = run(started(cfg), actions())
    del env
    gc.collect()
    back = pickle.loads(blob)                         # its MuJoCo data and model are its own
    assert same(run(back, actions()), ref)
    back.reset(seed=11)
    fresh = LhdLoadingEnv("rld", cfg)
    fresh.reset(seed=11)
    assert same(run(back, actions(seed=1)), run(fresh, actions(seed=1)))


def test_a_reset_that_raises_leaves_nothing_to_step(cfg):
    env = started(cfg)
    with pytest.raises(ValueError, match=r"options\['d_attack'\] = 5.0: expected metres in \(0, 1\]"):
        env.reset(options={"d_attack": 5.0})
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(PUSH)


def test_a_stalled_attack_is_drawn_again_inside_reset_unless_asked_not_to(cfg, monkeypatch):
    env = LhdLoadingEnv("rld", cfg)
    real, calls = env.sim.reset, []

    def stalls_twice(*a, **k):
        calls.append(1)
        if len(calls) <= 2:
            raise AttackError("attack drive stalled 3 mm short of d_init (test)")
        return real(*a, **k)
    monkeypatch.setattr(env.sim, "reset", stalls_twice)
    _, info = env.reset(seed=0)
    assert info["attack_redraws"] == 2 and len(calls) == 3
    env.step(PUSH)                                    # a live episode
    calls.clear()
    env.attack_redraws = 0
    with pytest.raises(AttackError, match="stalled"):
        env.reset(seed=0)


@pytest.mark.parametrize("kwargs, match", [
    ({"randomize": "no"}, "randomize = 'no': expected True or False"),
    ({"deploy_filter": "false", "variant": "rlc"}, "deploy_filter = 'false': expected True or False"),
    ({"deploy_filter": True}, "the rld variant has no such filter"),
    ({"render_mode": "rgb_array"}, "renders nothing"),
    ({"attack_redraws": -1}, "attack_redraws = -1: expected an integer >= 0"),
])
def test_constructor_flags_are_checked(cfg, kwargs, match):
    with pytest.raises(ValueError, match=match):
        LhdLoadingEnv(**{"variant": "rld", "config": cfg, **kwargs})


def test_numpy_numbers_are_numbers_and_attack_options_are_checked(cfg):
    env = LhdLoadingEnv("rld", cfg, slope_deg=np.float32(20.0))
    env.reset(seed=0, options={"slope_deg": np.int64(25)})
    assert abs(np.degrees(env.sim.pile.alpha) - 25.0) < 1e-9
    with pytest.raises(ValueError, match="outside the configured pile range"):
        env.reset(options={"slope_deg": True})
    for opt, match in (({"d_attack": -1.0}, "d_attack"), ({"d_attack": float("nan")}, "d_attack"),
                       ({"attack_speed": 5.0}, r"attack_speed'\] = 5.0: expected a wheel speed in \(0, 2.7\]"),
                       ({"attack_speed": 0.0}, "attack_speed")):
        with pytest.raises(ValueError, match=match):
            env.reset(options=opt)
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.reset(seed=0)
