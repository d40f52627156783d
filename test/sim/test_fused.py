"""The compiled chunk loop (lhd_sim_node/fused.py) is the Python-driven loop, bit for bit.

Two environments with the same seeds and actions, one stepping through fused.run_chunks (MuJoCo's
C API called from numba), one through Simulator._physics + mujoco.mj_kinematics, must hold the
same MuJoCo state, pile, payload and kernel state after every step: in nominal episodes, with
randomised conditions (actuator dead times split the period into several runs of chunks,
heading and offset), with the FEE off, and through the twin's chunk-wise advance()."""
import numpy as np
import pytest

from lhd_sim_node import fused
from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.simulator import AttackError


def _snapshot(env: LhdLoadingEnv) -> dict:
    s, m, d = env.sim, env.sim.model, env.sim.data
    return {
        "time": np.array([d.time]), "qpos": d.qpos.copy(), "qvel": d.qvel.copy(), "act": d.act.copy(),
        "ctrl": d.ctrl.copy(), "xfrc": d.xfrc_applied.copy(), "tendon_fl": m.tendon_frictionloss.copy(),
        "dof_fl": m.dof_frictionloss.copy(), "body_mass": m.body_mass.copy(), "top": s.pile.top.copy(),
        "site_xpos": d.site_xpos.copy(), "kst": s._kst.copy(),
        "payload": np.array([s.loaded_mass, s.spilled_mass, s.V_cut, s.W_ideal, s._fee_h, s._fee_v, s._alpha_s]),
    }


def _assert_same(a: dict, b: dict, where: str) -> None:
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=f"{k} differs {where}")


def _pair(randomize: bool = False):
    fast, slow = LhdLoadingEnv(randomize=randomize), LhdLoadingEnv(randomize=randomize)
    slow.sim.fused = False
    return fast, slow


def test_the_library_is_found_and_used_here():
    # this project's machines (Linux wheels of mujoco) have the library; a platform without it
    # falls back to the Python loop (test below), it does not fail
    assert fused.AVAILABLE
    assert LhdLoadingEnv().sim.fused


def _run(fast, slow, seed: int, steps: int, rng) -> int:
    ra, rb = fast.reset(seed=seed), slow.reset(seed=seed)
    np.testing.assert_array_equal(ra[0], rb[0])
    _assert_same(_snapshot(fast), _snapshot(slow), f"after the attack drive (seed {seed})")
    # the attack drive's drift marks (time, x, wheel angles of its last chunks): the same floats
    assert list(fast.sim._drift_marks) == list(slow.sim._drift_marks)
    assert fast.sim._drift_from == slow.sim._drift_from and len(fast.sim._drift_marks) == 5
    n = 0
    for k in range(steps):
        a = rng.uniform(-1.0, 1.0, 3)
        oa, rwa, ta, tra, _ = fast.step(a)
        ob, rwb, tb, trb, _ = slow.step(a)
        n += 1
        np.testing.assert_array_equal(oa, ob)
        assert (rwa, ta, tra) == (rwb, tb, trb)
        _assert_same(_snapshot(fast), _snapshot(slow), f"after step {k} (seed {seed})")
        if ta or tra:
            break
    return n


def test_nominal_episodes_are_bit_identical():
    fast, slow = _pair()
    rng = np.random.default_rng(3)
    steps = sum(_run(fast, slow, seed, 60, rng) for seed in (0, 1, 2))
    assert steps >= 30      # real episodes were compared, not just resets


def test_randomised_episodes_with_dead_times_are_bit_identical():
    fast, slow = _pair(randomize=True)
    rng = np.random.default_rng(4)
    split = 0
    for seed in range(6):
        _run(fast, slow, seed, 25, rng)
        dd, dh = fast.sim._delay_chunks
        split += (dd > 0) or (dh > 0)
    assert split >= 2, "no episode had an actuator dead time: the split runs of chunks were not compared"


def test_without_the_fee_and_through_advance():
    fast, slow = _pair()
    for e in (fast, slow):
        e.reset(seed=5)
        e.sim.fee_enabled = False
    for k in range(10):
        fast.sim.step(np.array([8.0, 0.0, 0.3]))
        slow.sim.step(np.array([8.0, 0.0, 0.3]))
    _assert_same(_snapshot(fast), _snapshot(slow), "with the FEE off")
    for e in (fast, slow):
        e.sim.fee_enabled = True
    for k in range(12):   # the twin's 20 ms chunks
        u = np.array([6.0, -0.2 if k > 5 else 0.0, 0.4])
        fast.sim.advance(u)
        slow.sim.advance(u)
        _assert_same(_snapshot(fast), _snapshot(slow), f"after advance {k}")
        assert fast.sim.wheel_drift() == slow.sim.wheel_drift()


def test_the_attack_timeout_still_fires():
    fast, slow = _pair()
    for e in (fast, slow):
        with pytest.raises(AttackError, match="did not reach d_init") as err:
            e.sim.reset(np.random.default_rng(0), attack_speed=0.0)
        e.err = str(err.value)
    assert fast.err == slow.err
    _assert_same(_snapshot(fast), _snapshot(slow), "after the attack timeout")
    assert list(fast.sim._drift_marks) == list(slow.sim._drift_marks)


@pytest.mark.parametrize("compiled", [True, False])
def test_an_instability_in_the_attack_drive_is_an_error(compiled, monkeypatch):
    """A non-finite velocity makes mj_step reset the data (time back to 0) and count a warning: the
    compiled drive's reproduced time would silently go on from the old one. Both drives raise
    SimulationError naming it instead of starting an episode from a reset machine."""
    import math
    from lhd_sim_node.simulator import SimulationError

    env = LhdLoadingEnv()
    env.sim.fused = compiled
    place = env.sim.place_machine

    def place_and_break(*a, **k):
        place(*a, **k)
        env.sim.data.qvel[0] = math.nan
    monkeypatch.setattr(env.sim, "place_machine", place_and_break)
    with pytest.raises(SimulationError, match="unstable during the attack drive"):
        env.reset(seed=1)
    monkeypatch.setattr(env.sim, "place_machine", place)
    env.reset(seed=1)          # a sound reset afterwards works


@pytest.mark.parametrize("compiled", [True, False])
def test_an_instability_in_a_step_is_an_error(compiled):
    """The same in an episode: a non-finite velocity mid-episode is a SimulationError, not a machine
    silently put back at its initial pose."""
    import math
    from lhd_sim_node.simulator import SimulationError

    env = LhdLoadingEnv()
    env.sim.fused = compiled
    env.reset(seed=2)
    env.step(np.array([1.0, 0.0, 0.0]))
    env.sim.data.qvel[0] = math.nan
    with pytest.raises(SimulationError, match="unstable"):
        env.step(np.array([1.0, 0.0, 0.0]))


def test_a_library_of_another_version_is_not_used(monkeypatch):
    """The library beside the bindings must be the version they report: else no compiled loop, and
    the reason (lhd bench sim prints it)."""
    import mujoco
    assert fused._load() == ""
    real = mujoco.mj_versionString()
    monkeypatch.setattr(mujoco, "mj_versionString", lambda: "0.0.1")
    reason = fused._load()
    assert f"is MuJoCo {real}, the bindings are 0.0.1" in reason
