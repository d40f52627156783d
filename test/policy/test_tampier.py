"""The Tampier-style heuristic (policy/tampier.py): its parameter file, the state machine on
hand-built input sequences (expected stages and commands counted by hand from the shipped
thresholds at 10 Hz), the policy node's decision path around it, and a short run in the simulator
(a physical check: it loads material and lifts the tip, not a score)."""
import math

import numpy as np
import pytest

from lhd_loading_ros.learning.baselines import conditions, evaluate_tampier, format_tampier, run_tampier_episode
from lhd_loading_ros.learning.evaluate import episode_conditions
from lhd_loading_ros.policy.core import ZERO_COMMAND, Inputs
from lhd_loading_ros.policy.tampier import (SCHEMA, TampierController, TampierCore, default_tampier_path,
                                            load_tampier_config, validate_tampier)
from lhd_loading_ros.task.config import ConfigError
from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.state import LhdState

DT = 0.1
ZONE = (0.52, 0.85, 0.35)          # end zone [x_min, x_max, z_min] of a 20 deg pile (sim, seed 0)
WHEELS, LIFT, CURL = 2.7, -0.191, 0.2   # full rates of the paper's actuator table (rad/s)
PUSH = (WHEELS, 0.0, 0.0)


@pytest.fixture(scope="module")
def tp():
    return load_tampier_config()


@pytest.fixture
def ctl(tp, params):
    return TampierController(tp, params, DT)


def st(v_x=0.35, drift=False, boom=0.0, bucket=0.0, pitch=None, x=0.3, z=0.01):
    """A task state: tip at (x, z), boom / bucket angles (rad), pitch = bucket - boom unless given."""
    return LhdState(x_shovel=x, y_shovel=0.0, z_shovel=z, phi_shovel=bucket - boom if pitch is None else pitch,
                    v_x=v_x, drift=drift, phi_boom=boom, dphi_boom=0.0, phi_bucket=bucket, dphi_bucket=0.0,
                    drift_front=drift, drift_rear=False)


def run(ctl, states):
    return [ctl.step(s, ZONE) for s in states]


# ------------------------------------------------------------------ parameter file
def test_shipped_parameters_load_and_each_is_explained(tp):
    assert tp.collision_speed_fraction == 0.5 and tp.collision_time == 0.3 and tp.pitch_full_deg == 45.0
    text = default_tampier_path().read_text()
    for key in SCHEMA:     # every threshold is in the file with its reason on the same line
        line = next(ln for ln in text.splitlines() if ln.strip().startswith(f"{key}:"))
        assert "#" in line and len(line.split("#", 1)[1].strip()) > 20, line


def test_bad_parameter_files_name_the_key(tmp_path, tp):
    good = {k: getattr(tp, k) for k in SCHEMA}
    for change, text in (({"collision_speed_fraction": 1.5}, "'tampier.collision_speed_fraction' = 1.5"),
                         ({"lift_time": "fast"}, "'tampier.lift_time' = 'fast'"),
                         ({"stall_time": math.nan}, "'tampier.stall_time' = nan"),
                         ({"lift_tme": 0.5}, "unknown key 'tampier.lift_tme'"),
                         ({"boom_full_deg": 60.0}, "boom_full_deg <= tampier.boom_top_deg")):
        with pytest.raises(ConfigError, match=text.replace("(", r"\(").replace(")", r"\)")):
            validate_tampier({**good, **change})
    missing = dict(good)
    del missing["bury_time"]
    with pytest.raises(ConfigError, match="missing key 'tampier.bury_time'"):
        validate_tampier(missing)
    f = tmp_path / "t.yaml"
    f.write_text("other: {}\n")
    with pytest.raises(ConfigError, match="one top-level section 'tampier'"):
        load_tampier_config(f)
    with pytest.raises(ConfigError, match="cannot read"):
        load_tampier_config(tmp_path / "none.yaml")


def test_durations_become_whole_control_periods(ctl):
    # 0.3 s / 0.1 s = 3, 0.2 s = 2, 0.5 s = 5 (shipped config)
    assert (ctl.n_collision, ctl.n_collision_drift, ctl.n_bury, ctl.n_stall, ctl.n_lift, ctl.n_tilt) == (3, 2, 3, 2, 5, 5)


# ------------------------------------------------------------------ the state machine, by hand
def test_collision_detected_on_a_speed_drop(ctl):
    # 5 periods at 0.35 m/s (approach speed 0.35), then 0.15 m/s < 0.5 * 0.35 = 0.175 m/s: the third
    # slow period (step 8) is the collision; every command until then and in bury: wheels only
    cmds = run(ctl, [st(0.35)] * 5 + [st(0.15)] * 3)
    assert ctl.collision_step == 8 and ctl.history == ["approach"] * 7 + ["bury"]
    assert cmds == [PUSH] * 8


def test_a_speed_that_never_drops_far_enough_keeps_pushing_until_the_supervisor_times_out(ctl):
    # 0.18 m/s stays above 0.175 m/s: no collision, no drift -> the arm never moves; 20 s of
    # pushing (twice the supervisor's 10 s timeout) and the heuristic never stops on its own
    cmds = run(ctl, [st(0.35)] * 3 + [st(0.18)] * 197)
    assert ctl.collision_step is None and set(ctl.history) == {"approach"}
    assert set(cmds) == {PUSH}
    # one slow period short of the three needed, repeatedly: still no collision
    ctl.reset()
    run(ctl, ([st(0.35)] + [st(0.1)] * 2) * 30)
    assert ctl.collision_step is None


def test_a_start_from_rest_is_no_collision(ctl):
    # the real attempt starts at rest 50 cm from the pile: slow, wheels slipping while they spin up;
    # below approach_min_speed (0.15 m/s) neither the low speed nor the drift is the collision
    run(ctl, [st(v, drift=True) for v in (0.0, 0.03, 0.06, 0.09, 0.12, 0.14)])
    assert ctl.collision_step is None and ctl.stage == "approach"
    # at speed now, two drifting periods are the collision
    run(ctl, [st(0.3), st(0.3, drift=True), st(0.3, drift=True)])
    assert ctl.collision_step == 9 and ctl.stage == "bury"


def test_lift_on_drift_then_tilt_then_bury_again(ctl):
    run(ctl, [st(0.35)] * 5 + [st(0.15)] * 3)            # collision at step 8, bury period 1
    # drifting from now on: bury lasts bury_time (3 periods: steps 8, 9, 10), then lift 5 (11-15),
    # tilt 5 (16-20), bury 3 (21-23), lift again (24-)
    cmds = run(ctl, [st(0.15, drift=True)] * 16)          # steps 9 .. 24
    assert ctl.history[7:] == ["bury"] * 3 + ["lift"] * 5 + ["tilt"] * 5 + ["bury"] * 3 + ["lift"]
    assert cmds[:2] == [PUSH] * 2
    assert cmds[2:7] == [(WHEELS, LIFT, 0.0)] * 5         # full-rate lift, wheels still pushing
    assert cmds[7:12] == [(WHEELS, 0.0, CURL)] * 5        # full-rate tilt
    assert cmds[12:15] == [PUSH] * 3 and cmds[15] == (WHEELS, LIFT, 0.0)


def test_a_stall_without_drift_also_lifts_and_free_pushing_does_not(ctl):
    run(ctl, [st(0.35)] * 5 + [st(0.15)] * 3)            # collision at step 8 (approach speed 0.35)
    run(ctl, [st(0.2)] * 10)                              # 0.2 > 0.3 * 0.35 = 0.105: moving, keeps burying
    assert ctl.stage == "bury"
    run(ctl, [st(0.1)])                                   # one stalled period: not yet
    assert ctl.stage == "bury"
    run(ctl, [st(0.1)])                                   # two: lift
    assert ctl.stage == "lift"


def test_curl_when_the_boom_is_up_then_raise_then_stop_in_the_end_zone(ctl, params):
    run(ctl, [st(0.35)] * 5 + [st(0.15)] * 3)            # bury
    b20 = math.radians(20.0) + 1e-6                       # boom lifted by boom_full_deg
    assert run(ctl, [st(0.1, boom=-b20, bucket=0.1)]) == [(WHEELS, 0.0, CURL)] and ctl.stage == "curl"
    # curling until the pitch reaches 45 deg
    assert run(ctl, [st(0.1, boom=-b20, pitch=math.radians(44.9))]) == [(WHEELS, 0.0, CURL)]
    assert run(ctl, [st(0.1, boom=-b20, pitch=math.radians(45.0))]) == [(WHEELS, LIFT, 0.0)]
    assert ctl.stage == "raise"
    # the boom stops lifting at boom_top_deg (50 deg); the wheels keep pushing
    assert run(ctl, [st(0.0, boom=-math.radians(50.1), pitch=math.radians(60), x=0.45, z=0.5)]) == [PUSH]
    # the tip enters the end zone (0.52 < x < 0.85, z > 0.35): stop, and stay stopped
    cmds = run(ctl, [st(0.1, boom=-0.5, pitch=0.9, x=0.6, z=0.36), st(0.3, drift=True, x=0.4, z=0.0)])
    assert cmds == [ZERO_COMMAND] * 2 and ctl.stage == "done"
    # a bucket at the end of its joint range counts as curled too
    ctl.reset()
    run(ctl, [st(0.35)] * 5 + [st(0.15)] * 3 + [st(0.1, boom=-b20)])
    assert ctl.stage == "curl"
    run(ctl, [st(0.1, boom=-b20, bucket=params.bucket_angle_max - 0.01, pitch=math.radians(30))])
    assert ctl.stage == "raise"


def test_commands_are_ternary_and_reset_starts_again(ctl, params):
    rng = np.random.default_rng(0)
    cmds = []
    for _ in range(300):
        cmds.append(ctl.step(st(rng.uniform(-0.05, 0.45), bool(rng.random() < 0.3), -rng.uniform(0, 1.0),
                                rng.uniform(0, 1.4), x=rng.uniform(0, 1.0), z=rng.uniform(0, 0.5)), ZONE))
    u = np.array(cmds)
    assert set(u[:, 0]) <= {0.0, WHEELS} and set(u[:, 1]) <= {0.0, LIFT} and set(u[:, 2]) <= {0.0, CURL}
    ctl.reset()
    assert (ctl.stage, ctl.v_approach, ctl.collision_step, ctl.history) == ("approach", 0.0, None, [])
    with pytest.raises(ValueError, match="v_x"):
        ctl.step(st(math.nan), ZONE)


# ------------------------------------------------------------------ through the policy node's decision path
def feed(inp, v_x, now, zone=ZONE, slope=math.radians(20.0)):
    """Inputs as the topics carry them: the machine in the attack pose at the origin of {M}."""
    inp.put("joints", {"boom": (0.0, 0.0), "bucket": (0.0, 0.0)}, now)
    inp.put("odom", ((0.0, 0.0, 0.137), (1.0, 0.0, 0.0, 0.0), v_x), now)
    inp.put("drift_front", False, now)
    inp.put("drift_rear", False, now)
    inp.put("slope", slope, now)
    inp.put("end_zone", zone, now)


def test_core_decides_through_the_shared_path(tp, params, cfg):
    core = TampierCore(tp, params, ArmKinematics.from_config(cfg), DT)
    inp = Inputs()
    d = core.decide(inp, 0.0, 0.5)
    assert d.command == ZERO_COMMAND and "no joints received yet" in d.reason and d.kind == "inputs"
    feed(inp, 0.35, 1.0)
    d = core.decide(inp, 1.0, 0.5)
    assert d.reason == "" and d.command == PUSH and d.note == "stage approach" and d.observation is None
    d = core.decide(inp, 1.7, 0.5)                         # every 10 Hz input 0.7 s old
    assert d.command == ZERO_COMMAND and "joints is 0.70 s old" in d.reason
    feed(inp, math.nan, 2.0)
    d = core.decide(inp, 2.0, 0.5)
    assert d.command == ZERO_COMMAND and d.kind == "bad_input"
    feed(inp, 0.35, 3.0, zone=(0.5, math.nan, 0.35))
    assert core.decide(inp, 3.0, 0.5).kind == "bad_input"
    feed(inp, 0.35, 4.0, slope=math.radians(40.0))         # no trained range: any finite slope
    assert core.decide(inp, 4.0, 0.5).command == PUSH
    core.reset()
    assert core.controller.stage == "approach" and core.controller.steps == 0


# ------------------------------------------------------------------ in the simulator
def test_in_the_simulator_it_detects_the_pile_lifts_and_loads(cfg, tp):
    """20 deg homogeneous pile: the collision is detected, a lift follows, material is loaded and
    the tip rises. Hand estimate of one lift: 0.5 s at 0.191 rad/s turns the boom 0.0955 rad; the
    tip lies 0.76 m ahead of the boom pivot in the attack pose (pivot 0.95 m, tip 0.95 + 0.461 +
    0.30 m from the rear axle), so it rises about 0.76 * 0.0955 = 0.073 m."""
    from lhd_sim_node.env import LhdLoadingEnv

    env = LhdLoadingEnv("rld", cfg)
    ctl = TampierController(tp, env.p)
    res, tr = run_tampier_episode(env, ctl, 0, {"slope_deg": 20.0, "material": "homogeneous"})
    assert ctl.collision_step is not None and "lift" in tr["stage"]
    k = tr["stage"].index("lift")                          # trace index k+1 is the state after step k+1
    z_before = tr["z"][k]
    assert res.loaded > 0.0 and tr["loaded"][-1] == res.loaded
    assert max(tr["z"][k + 1:]) - z_before >= 0.5 * 0.073, (z_before, max(tr["z"]))
    # "never stops accelerating until the end": full wheel speed in every stage but done
    assert all(c[0] == WHEELS for c, stage in zip(tr["command"], tr["stage"]) if stage != "done")


def test_evaluation_uses_the_actors_stratified_set_and_reports_the_papers_metrics(cfg, tp):
    from lhd_sim_node.env import LhdLoadingEnv

    for i in range(10):
        assert conditions(i, 7) == episode_conditions(i, 7)
    assert conditions(5, 0, (15.0, 30.0), ("homogeneous",)) == (5, {"slope_deg": 30.0, "material": "homogeneous"})
    env = LhdLoadingEnv("rld", cfg)
    res = evaluate_tampier(env, 2, 100, cfg["task"]["bucket_capacity"], tp, (20.0, 25.0), ("homogeneous",), 10.0)
    assert res["episodes"] == 2 and set(res["by_slope"]) == {"20", "25"}
    # every attempt ends one way: restricted zone, timeout (failed), success at the timeout, end zone
    assert (sum(res["failures"][k] for k in ("restricted_zone", "timeout")) + res["successes_at_timeout"]
            + round(res["end_zone_rate"] * 2)) == 2
    assert all(r["elapsed_s"] <= 10.0 + 1e-9 for r in res["episodes_list"])
    assert "Tampier-style heuristic, time limit 10 s" in format_tampier(res)
    with pytest.raises(ValueError, match="slope"):
        evaluate_tampier(env, 1, 0, 30.0, tp, (40.0,), ("homogeneous",))
