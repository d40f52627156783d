"""The drift flag as the machine's bridge gives it (randomization.drift_flag_lag_max_s, LhdSimulator.drift_flag,
`lhd eval --stress rest_bridge`): the paper's rule (wheel rim travel against machine travel over one control
period) over a period that ends some 20 ms chunks before the observation, as the bridge's window ends at its
newest camera image. The expectations come from the machine's coordinates recorded here chunk by chunk
(LhdSimulator.advance, one chunk per call) and the rule written out again, not from the simulator's own drift code."""
import copy
import math

import numpy as np
import pytest

from lhd_loading_ros.task.randomization import NOMINAL, Conditions
from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.simulator import LhdSimulator


@pytest.fixture(scope="module")
def cfg():
    from lhd_loading_ros.task.config import load_config
    return load_config()


FIXED = dict(alpha=math.radians(15.0), material="homogeneous", d_attack=0.15, attack_speed=2.7)


def _by_hand(sim, a, b):
    """(front, rear) by the paper's rule between two recorded coordinate rows (time, x, wheel angles fl, fr, rl, rr):
    a wheel drifts when |r dtheta - dx| > max(v_min T, ratio x the larger of the two)."""
    T, dx = b[0] - a[0], b[1] - a[1]
    r, v_min, ratio = sim.wheel_radius, sim.p.drift_min_speed, sim.p.drift_slip_ratio
    slip = [abs(r * (b[2 + k] - a[2 + k]) - dx) > max(v_min * T, ratio * max(abs(r * (b[2 + k] - a[2 + k])), abs(dx)))
            for k in range(4)]
    return slip[0] or slip[1], slip[2] or slip[3]


def _coords(sim):
    q = sim.data.qpos
    return (float(sim.data.time), float(q[0]), *[float(q[i]) for i in sim._wheel_qs])


def _expected_window(rec, armed, lag, n, chunk_s):
    """The window by hand over the recorded boundary rows: the period ending `lag` rows back, its start n rows
    before that, or, reaching before the arming, the armed coordinates a period before the end."""
    e = len(rec) - 1 - lag
    if e <= 0:
        return None
    return (rec[e - n] if e >= n else (rec[e][0] - n * chunk_s, *armed[1:])), rec[e]


@pytest.mark.parametrize("fused", [True, False])
def test_lagged_windows_against_the_rule_by_hand_on_a_start_from_rest(cfg, fused):
    """A start from rest on a 15 deg pile, full wheels, chunk by chunk (advance: the twin's grain). Every lag's window
    is exactly the recorded rows of the period ending that many chunks back (start and end, times included), and
    its flag the rule by hand over them; a window that reaches before the arming sees the machine stand there. Lag
    0 at a period's end is the simulator's own window. And the point of it: at the first observation, windows that
    straddle the start flag drift (the wheels spin up ahead of the machine), while the simulator's own window, the
    whole first period, does not."""
    sim = LhdSimulator(cfg)
    sim.fused = fused and sim.fused
    sim.reset(np.random.default_rng(4), conditions=Conditions(rest_start=True, drift_flag_lag_max_s=0.14), **FIXED)
    n = sim.n_phys // sim.fee_every
    assert n == 5 and abs(sim.fee_dt - 0.02) < 1e-12
    rec = [_coords(sim)]
    armed = rec[0]
    u = np.array([sim.p.wheels_max, 0.0, 0.0])
    straddling, own = [], []
    for chunk in range(1, 3 * n + 1):
        sim.advance(u)
        rec.append(_coords(sim))
        for lag in range(0, 8):
            window = _expected_window(rec, armed, lag, n, sim.fee_dt)
            assert sim.drift_window(lag) == window, (chunk, lag)
            want = (False, False) if window is None else _by_hand(sim, *window)
            assert sim.drift_flag(lag) == want, (chunk, lag)
            if chunk % n == 0 and lag == 0:
                assert sim.drift_flag(0) == sim.wheel_drift()
            if chunk == n and 1 <= lag < n:        # windows that end inside the first period
                straddling.append(any(want))
        if chunk == n:
            own.append(any(sim.wheel_drift()))
    assert any(straddling) and own == [False], (straddling, own)


@pytest.mark.parametrize("slope", [15.0, 25.0, 35.0])
def test_lagged_windows_by_hand_under_random_commands_through_step(cfg, slope):
    """Random commands, a dead time on the hydraulics (step runs a period in two calls), starts at the attack speed
    and from rest. The coordinates are recorded here after every physics chunk by a wrapper around the Python path's
    chunk (LhdSimulator._physics), not by the history's code: after every step the history ends at MuJoCo's time,
    and every lag's window is exactly the recorded rows. The compiled path keeps the same history, bit for bit."""
    for rest in (False, True):
        a, c = LhdSimulator(cfg), LhdSimulator(cfg)
        a.fused = False
        rec = []
        physics = a._physics

        def chunk_and_record(nstep):
            physics(nstep)
            rec.append(_coords(a))

        fixed = dict(FIXED, alpha=math.radians(slope))
        cond = Conditions(rest_start=rest, hydraulic_delay_s=0.04, drift_flag_lag_max_s=0.14)
        a.reset(np.random.default_rng(11), conditions=cond, **fixed)
        c.reset(np.random.default_rng(11), conditions=cond, **fixed)
        a._physics = chunk_and_record
        rec[:] = [_coords(a)]                  # from the arming (or the attack drive's end) on
        armed = rec[0]
        n = a.n_phys // a.fee_every
        rng = np.random.default_rng(int(slope) + rest)
        for step in range(12):
            u = np.array([rng.uniform(0.0, 2.7), rng.choice([-0.19, 0.0, 0.19]), rng.choice([-0.2, 0.0, 0.3])])
            a.step(u)
            c.step(u)
            assert len(rec) == 1 + n * (step + 1)
            assert a._chunk_hist[-1] == rec[-1] and rec[-1][0] == a.data.time
            assert list(c._chunk_hist) == list(a._chunk_hist)
            for lag in range(0, 8):
                if not rest and len(rec) - 1 - lag - n < 0:
                    continue                   # at the attack speed the history before the arming is the drive's
                assert a.drift_window(lag) == _expected_window(rec, armed, lag, n, a.fee_dt), (rest, step, lag)


def test_the_history_leaves_the_physics_alone_and_lag_zero_is_the_simulators_window(cfg):
    """Recording the chunk history (the marked compiled loop) runs the same physics, bit for bit, through
    dead-time splits of the period too; at lag 0 the flag is wheel_drift's at every step's end."""
    a, b = LhdSimulator(cfg), LhdSimulator(cfg)
    delay = dict(drive_delay_s=0.04, hydraulic_delay_s=0.06)
    a.reset(np.random.default_rng(7), conditions=Conditions(**delay), **FIXED)
    b.reset(np.random.default_rng(7), conditions=Conditions(**delay, drift_flag_lag_max_s=0.1), **FIXED)
    rng = np.random.default_rng(1)
    for _ in range(15):
        u = np.array([rng.uniform(0.0, 2.7), rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.3)])
        a.step(u)
        b.step(u)
        np.testing.assert_array_equal(a.data.qpos, b.data.qpos)
        np.testing.assert_array_equal(a.data.qvel, b.data.qvel)
        assert b.drift_flag(0) == b.wheel_drift() == a.wheel_drift()


def test_bad_lags_are_refused(cfg):
    sim = LhdSimulator(cfg)
    sim.reset(np.random.default_rng(4), **FIXED)
    with pytest.raises(RuntimeError, match="drift_flag_lag_max_s is 0"):
        sim.drift_flag(0)
    sim.reset(np.random.default_rng(4), conditions=Conditions(drift_flag_lag_max_s=0.1), **FIXED)
    for bad in (-1, 26, 1.5, True, np.bool_(True)):
        with pytest.raises(ValueError, match="lag_chunks"):
            sim.drift_flag(bad)
    for bad in (0.6, float("nan"), -0.02, 0.15, 0.01):     # outside 0..0.5 s, or not a whole number of 20 ms chunks
        with pytest.raises(ValueError, match="drift_flag_lag_max_s .* expected a multiple of the 0.02 s chunk"):
            sim.reset(np.random.default_rng(4), conditions=Conditions(drift_flag_lag_max_s=bad), **FIXED)
    # the schema's limit is the history's
    from lhd_loading_ros.task.config import SCHEMA
    from lhd_sim_node.simulator import DRIFT_LAG_LIMIT_S
    assert SCHEMA["randomization"]["drift_flag_lag_max_s"] == ("float", 0.0, DRIFT_LAG_LIMIT_S)


def test_the_environment_observes_the_lagged_flag_and_scores_its_own(cfg):
    """In the environment the observation's drift entry, and the measured state the scripted controllers read, carry
    the flag of the window that ends the drawn number of chunks back (0..7 at 0.14 s, from the lag's own stream,
    reproduced here from a copy of it), the episode's drift figures the simulator's own window: the sensor's error
    reaches what the sensors give only. Some steps of these starts from rest observe a flag the own window does not."""
    env = LhdLoadingEnv("rld", cfg, slope_deg=15.0)
    lags, differ = set(), 0
    for seed in range(6):
        obs, _ = env.reset(seed=seed, options={"conditions": Conditions(rest_start=True, drift_flag_lag_max_s=0.14)})
        g, prev = copy.deepcopy(env._lag_rng), env._lag_prev     # the lag's stream, and the first observation's lag
        assert 0 <= prev <= 7
        for k in range(4):
            obs, _, term, trunc, info = env.step(np.array([1.0, 0.0, 0.0], dtype=np.float32))
            lag = min(int(g.integers(0, 8)), prev + 5)     # never ending before the last window ended
            assert env._lag_prev == lag, (seed, k)          # the environment's own lag, capped as by hand
            prev = lag
            lags.add(lag)
            want = env.sim.drift_flag(lag)
            assert bool(obs[5]) == any(want), (seed, k, lag)
            m = env.measured_state
            assert (m.drift_front, m.drift_rear, m.drift) == (*want, any(want))
            assert (info["drift_front"], info["drift_rear"]) == env.sim.wheel_drift()
            assert (env.state.drift_front, env.state.drift_rear) == env.sim.wheel_drift()
            differ += int(bool(obs[5]) != any(env.sim.wheel_drift()))
    assert differ > 0 and len(lags) >= 5, (differ, lags)
    # without the key the observation carries the simulator's own window
    obs, _ = env.reset(seed=0, options={"conditions": Conditions(rest_start=True)})
    for _ in range(3):
        obs, _, _, _, info = env.step(np.array([1.0, 0.0, 0.0], dtype=np.float32))
        assert bool(obs[5]) == (info["drift_front"] or info["drift_rear"])


def test_the_lag_leaves_the_sensor_noise_of_an_episode_alone(cfg):
    """`--stress machine` against `machine_bridge`: the same episode seed gives the same machine, the same camera
    noise and dropouts, the same arm-sensor noise; only the drift entry of the observation may differ."""
    from dataclasses import replace

    from lhd_loading_ros.task.randomization import stress_conditions

    base = replace(stress_conditions("machine", 0, cfg), arm_angle_noise_deg=0.1, arm_encoder_counts=4096)
    a = LhdLoadingEnv("rld", cfg, slope_deg=20.0)
    b = LhdLoadingEnv("rld", cfg, slope_deg=20.0)
    oa, _ = a.reset(seed=5, options={"conditions": base})
    ob, _ = b.reset(seed=5, options={"conditions": replace(base, drift_flag_lag_max_s=0.14)})
    rng = np.random.default_rng(2)
    for _ in range(15):
        mask = np.arange(12) != 5
        np.testing.assert_array_equal(oa[mask], ob[mask])
        act = rng.uniform(-1.0, 1.0, 3).astype(np.float32)
        oa, _, ta, tra, _ = a.step(act)
        ob, _, tb, trb, _ = b.step(act)
        np.testing.assert_array_equal(a.sim.data.qpos, b.sim.data.qpos)
        if ta or tra:
            assert (ta, tra) == (tb, trb)
            break



def test_the_key_is_drawn_without_a_number_out_of_the_hash_at_zero_and_the_stress_cases(cfg):
    from dataclasses import replace

    from lhd_loading_ros.task.config import ConfigError, config_hash, hash_matches, validate
    from lhd_loading_ros.task.randomization import (DRIFT_FLAG_LAG_S, RandomizationRanges, draw,
                                                    stress_conditions)

    on = copy.deepcopy(cfg)
    on["randomization"].update(enabled=1, drift_flag_lag_max_s=0.14)
    off = copy.deepcopy(cfg)
    off["randomization"]["enabled"] = 1
    assert cfg["randomization"]["drift_flag_lag_max_s"] == 0.0
    ra, rb = np.random.default_rng(9), np.random.default_rng(9)
    c_on, c_off = draw(ra, RandomizationRanges.from_config(on)), draw(rb, RandomizationRanges.from_config(off))
    assert c_on.drift_flag_lag_max_s == 0.14 and replace(c_on, drift_flag_lag_max_s=0.0) == c_off
    assert ra.bit_generator.state == rb.bit_generator.state       # no number drawn for it
    assert config_hash(off) == config_hash({**off, "randomization": {k: v for k, v in off["randomization"].items()
                                                                      if k != "drift_flag_lag_max_s"}})
    assert config_hash(on) != config_hash(off)
    assert hash_matches(config_hash(off), on)                   # an actor trained before the key runs on a file with it
    for value in (0.7, 0.15):            # past the history's 0.5 s; not a whole number of 20 ms chunks
        bad = copy.deepcopy(cfg)
        bad["randomization"]["drift_flag_lag_max_s"] = value
        with pytest.raises(ConfigError, match="drift_flag_lag_max_s"):
            validate(bad)
    assert stress_conditions("rest_bridge", 3, cfg) == Conditions(rest_start=True, drift_flag_lag_max_s=DRIFT_FLAG_LAG_S)
    for i in (0, 8, 16, 24):
        assert stress_conditions("machine_bridge", i, cfg) == replace(stress_conditions("machine", i, cfg),
                                                                       drift_flag_lag_max_s=DRIFT_FLAG_LAG_S)
    assert NOMINAL.drift_flag_lag_max_s == 0.0


def test_the_windows_end_never_goes_back():
    """drift_lag_chunks by hand: one integer of U{0..n} per observation, taken as it is unless the window would end
    before the last one ended (end = k periods - lag); over many draws the ends never go back, the cap bites in the
    share of pairs counted by hand (lag_k+1 > lag_k + 5 with both U{0..7}: 3 of 64 pairs), and the first observation's
    lag is the raw draw."""
    from lhd_sim_node.env import drift_lag_chunks

    g, h = np.random.default_rng(11), np.random.default_rng(11)
    prev, ends, capped = None, [], 0
    for k in range(20000):
        lag = drift_lag_chunks(g, 0.14, 0.02, prev, 0.1)
        raw = int(h.integers(0, 8))
        assert 0 <= lag <= 7
        if prev is None:
            assert lag == raw
        else:
            assert lag == min(raw, prev + 5)
            capped += int(lag != raw)
        ends.append(5 * k - lag)
        prev = lag
    assert all(b >= a for a, b in zip(ends, ends[1:]))
    # the cap's share by hand: it bites when the raw draw exceeds prev + 5, i.e. prev 0 with raw 6 or 7, prev 1 with
    # raw 7; the cap never yields 0 or 1 (it yields prev + 5 >= 5), so P(prev = 0) = P(prev = 1) = 1/8 as drawn, and
    # the share is (1/8)(2/8) + (1/8)(1/8) = 3/64 = 4.69 % (binomial sd over 19,999 pairs 0.15 %)
    assert abs(capped / 19999 - 3 / 64) < 0.006, capped / 19999
    with pytest.raises(ValueError, match="lag_max_s"):
        drift_lag_chunks(np.random.default_rng(0), -0.02, 0.02, None, 0.1)
