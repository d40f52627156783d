"""The policy node's `teacher` controller (policy/teacher.py): its setting read from the training's
keys, the shared decision path, and the controller driving the real simulator from measurements
(odometry, joint angles, drift flags, the end zone) exactly as the training's demonstrations drive
it from the environment's own state, on a pile told the truth and on a 15 deg pile told 30 deg."""
import copy
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from lhd_loading_ros.learning.demonstrations import demo_action
from lhd_loading_ros.policy.core import ZERO_COMMAND, Inputs
from lhd_loading_ros.policy.teacher import TeacherCore, TeacherSetting
from lhd_loading_ros.task.actions import to_actuator
from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.randomization import Conditions
from test_policy_core import measurements

ROOT = Path(__file__).resolve().parents[2]
ZONE = (0.52, 0.85, 0.35)                 # end zone [x_min, x_max, z_min] of a 20 deg pile
WHEELS = 2.7                              # rad/s: full wheel rate (the paper's actuator table)


def test_the_setting_is_the_trainings():
    """From config/lhd_params.yaml read here as plain YAML: crowd = the middle of
    [demo_crowd_min, demo_crowd_max] = (0.5 + 0.75) / 2 = 0.625, pre-curl 0.3 rad, end-zone stop
    0.2 m, told zones on."""
    t = yaml.safe_load((ROOT / "config" / "lhd_params.yaml").read_text())["training"]
    assert (t["demo_crowd_min"], t["demo_crowd_max"], t["demo_pre_curl"]) == (0.5, 0.75, 0.3)
    s = TeacherSetting.from_config({"training": t})
    assert s == TeacherSetting(0.625, 0.3, True, 0.2)
    # a file without the told-teacher keys: the stop is off
    old = {k: v for k, v in t.items() if k not in ("demo_told_zones", "demo_end_zone_stop")}
    assert TeacherSetting.from_config({"training": old}).as_tuple() == (0.625, 0.3, False, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("key,value,expected", [
    ("demo_crowd_max", 1.5, "demo_crowd_min / demo_crowd_max = 0.5 / 1.5"),
    ("demo_crowd_min", 0.0, "demo_crowd_min / demo_crowd_max = 0 / 0.75"),
    ("demo_pre_curl", float("nan"), "training.demo_pre_curl = nan"),
    ("demo_pre_curl", 2.0, "training.demo_pre_curl = 2.0"),
    ("demo_end_zone_stop", -0.1, "training.demo_end_zone_stop = -0.1"),
    ("demo_push_curl", 1.5, "training.demo_push_curl = 1.5"),
    ("demo_late_lift", float("nan"), "training.demo_late_lift = nan"),
])
def test_a_bad_setting_names_the_key(cfg, key, value, expected):
    """A mapping built by hand (load_config refuses such a parameter file before this is reached)."""
    c = copy.deepcopy(cfg)
    c["training"][key] = value
    with pytest.raises(ValueError, match=expected.replace(".", r"\.").replace("/", "/")):
        TeacherSetting.from_config(c)


def feed(inp, now, v_x=0.35, zone=ZONE, slope=math.radians(20.0), boom=0.0, bucket=0.0, drift=False, x_tip=0.1):
    """Inputs as the topics carry them: the rear axle centre 1.711 m behind the tip (the attack pose,
    test_policy_gating's Rig), the tip x_tip into {M}."""
    inp.put("joints", {"boom": (boom, 0.0), "bucket": (bucket, 0.0)}, now)
    inp.put("odom", ((x_tip - 1.711, 0.0, 0.137), (1.0, 0.0, 0.0, 0.0), v_x), now)
    inp.put("drift_front", drift, now)
    inp.put("drift_rear", False, now)
    inp.put("slope", slope, now)
    inp.put("end_zone", zone, now)


def test_the_core_decides_through_the_shared_path(cfg, params):
    core = TeacherCore(TeacherSetting(0.625, 0.3, True, 0.2), params, ArmKinematics.from_config(cfg))
    inp = Inputs()
    d = core.decide(inp, 0.0, 0.5)
    assert d.command == ZERO_COMMAND and "no joints received yet" in d.reason
    # before x_min: wheels full, arm still
    feed(inp, 1.0)
    d = core.decide(inp, 1.0, 0.5)
    assert d.reason == "" and d.command == (WHEELS, 0.0, 0.0) and d.note == "stage approach"
    # a wheel drifts before x_min: it starts to curl (boom still) with the wheels at 0.625 of full speed
    feed(inp, 2.0, drift=True)
    d = core.decide(inp, 2.0, 0.5)
    u_crowd = to_actuator(np.array([0.25, 1.0, 1.0]), params)
    assert d.command == pytest.approx(tuple(u_crowd)) and d.note == "stage pre-curl"
    assert d.command[0] == pytest.approx(0.625 * WHEELS)
    # stale inputs, NaN and a malformed end zone: the zero command
    assert core.decide(inp, 2.7, 0.5).command == ZERO_COMMAND
    feed(inp, 3.0, v_x=math.nan)
    assert core.decide(inp, 3.0, 0.5).kind == "bad_input"
    feed(inp, 4.0, zone=(0.52, math.nan, 0.35))
    assert core.decide(inp, 4.0, 0.5).kind == "bad_input"
    # it never reads the slope: no trained range to refuse
    feed(inp, 5.0, slope=math.radians(40.0))
    assert core.decide(inp, 5.0, 0.5).command == (WHEELS, 0.0, 0.0)


def test_a_drift_flag_must_hold_before_it_starts_the_lift(cfg, params):
    """drift_confirm = 3: the start-up slip of the machine's wheels (one or two decisions with a drift
    flag, the camera's v_x still near 0) leaves the arm still; a flag up three decisions in a row (a
    stall) starts the curl; a flag that drops in between counts again from the start."""
    core = TeacherCore(TeacherSetting(0.625, 0.3, True, 0.2), params, ArmKinematics.from_config(cfg), 3)
    inp = Inputs()
    push, curl = (WHEELS, 0.0, 0.0), tuple(to_actuator(np.array([0.25, 1.0, 1.0]), params))
    cmds = []
    for k, drift in enumerate([True, True, False, True, True, True]):
        feed(inp, float(k), v_x=0.0 if k < 2 else 0.3, drift=drift)
        cmds.append(core.decide(inp, float(k), 0.5).command)
    assert cmds[:5] == [push] * 5 and cmds[5] == pytest.approx(curl)
    core.reset()
    feed(inp, 10.0, drift=True)
    assert core.decide(inp, 10.0, 0.5).command == push          # the count starts again with each attempt
    # one drift sample held (no newer one arrives within the input timeout): it counts once
    assert [core.decide(inp, 10.0 + 0.1 * k, 0.5).command for k in range(1, 5)] == [push] * 4
    assert core.drift_run == 1
    # a zero command (here a stale input) between flags starts the count again
    core.reset()
    for k in range(2):
        feed(inp, 20.0 + 0.1 * k, drift=True)
        core.decide(inp, 20.0 + 0.1 * k, 0.5)
    assert core.drift_run == 2
    assert core.decide(inp, 21.0, 0.5).command == ZERO_COMMAND and core.stage == "zero command"
    feed(inp, 21.1, drift=True)
    assert core.decide(inp, 21.1, 0.5).command == push and core.drift_run == 1
    # 1: the training's teacher, a single flag starts the curl
    one = TeacherCore(core.setting, params, ArmKinematics.from_config(cfg))
    assert one.decide(inp, 10.0, 0.5).command == pytest.approx(curl)
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="drift_confirm"):
            TeacherCore(core.setting, params, ArmKinematics.from_config(cfg), bad)


def drive(env, core, reset_opts, seed, told):
    """One attempt of TeacherCore on the simulator, fed what the sim node publishes (measurements)
    and the zones the end-zone node would publish (env.zones: built from the told slope); at every
    step the command must be the training demonstration's for the environment's own state. This
    checks the measurement path (forward kinematics, drift flags, zones, actuator map) against the
    environment's state; the maneuver itself is checked by hand, state by state, in
    test/learning/test_demonstrations.py::test_the_end_zone_stop_by_hand."""
    env.reset(seed=seed, options=reset_opts)
    st = core.setting
    z = env.zones
    inp, stages = Inputs(), []
    core.reset()
    now = 0.0
    while True:
        now += env.p.control_dt
        pos, quat, v, joints, f, r = measurements(env)
        for name, value in (("joints", joints), ("odom", (pos, quat, v)), ("drift_front", f), ("drift_rear", r),
                            ("slope", math.radians(told)), ("end_zone", (z.x_min, z.x_max, z.z_min))):
            inp.put(name, value, now)
        d = core.decide(inp, now, 0.5)
        assert d.reason == "", d.reason
        ref = to_actuator(demo_action(env, st.crowd, st.pre_curl, True, st.end_zone_stop), env.p)
        np.testing.assert_allclose(d.command, ref, atol=1e-12)
        stages.append(d.note)
        _, _, term, trunc, info = env.step_actuator(np.asarray(d.command))
        if term or trunc:
            return info["episode_result"], stages


def test_in_the_simulator_it_is_the_training_teacher(cfg):
    """Command for command the demonstrations' maneuver, from the machine's measurements: on a
    20 deg pile told the truth it succeeds; on a 15 deg pile told 30 deg (zones from the told slope,
    x_max 0.88 m where the pile's own is 1.29 m) it stops the wheels near the told x_max, lifts in
    place and succeeds with more than the success test's 20 kg (test_demonstrations has the pile's
    zones teacher failing there)."""
    from lhd_sim_node.env import LhdLoadingEnv

    env = LhdLoadingEnv("rld", cfg, zones_from_estimate=True)
    core = TeacherCore(TeacherSetting.from_config(cfg), env.p, ArmKinematics.from_config(cfg))
    res, stages = drive(env, core, {"slope_deg": 20.0, "material": "homogeneous"}, 3, 20.0)
    assert res.success and res.loaded > 20.0
    assert stages[0] == "stage approach" and "stage lift and curl" in stages
    res, stages = drive(env, core, {"slope_deg": 15.0, "material": "homogeneous",
                                    "conditions": Conditions(slope_error_deg=15.0)}, 5, 30.0)
    assert env.zones.x_max == pytest.approx(0.88, abs=0.02)
    assert "stage lift and curl in place" in stages
    assert res.success and res.reached_end_zone and res.loaded > 20.0


def test_the_push_curl_maneuver_by_hand(cfg):
    """maneuver.push_curl_action state by state, end zone x_min 0.54, x_max 0.88, z_min 0.35 (a 15
    deg pile told 30 deg), push_curl 0.3 rad, late_lift 0.85 (x_lift = 0.54 + 0.85 x 0.34 = 0.829 m),
    crowd 0.6, pre-curl 0.3, end-zone stop 0.2 m."""
    from dataclasses import replace

    from lhd_loading_ros.policy.maneuver import LATE_STOP_0, LATE_STOP_K, PUSH_CURL_LEAD, push_curl_action
    from lhd_loading_ros.task.state import LhdState

    s0 = LhdState(x_shovel=0.2, y_shovel=0.0, z_shovel=0.02, phi_shovel=0.0, v_x=0.3, drift=False, phi_boom=0.0,
                  dphi_boom=0.0, phi_bucket=0.0, dphi_bucket=0.0)
    x_min, x_max, z_min, crowd = 0.54, 0.88, 0.35, 0.6

    def act(s, mem):
        return push_curl_action(s, x_min, x_max, z_min, mem, 0.3, 0.85, crowd, 0.3, 0.2)

    assert PUSH_CURL_LEAD == 0.15
    mem = {}
    np.testing.assert_array_equal(act(s0, mem), [1.0, 1.0, -1.0])                        # level push
    np.testing.assert_array_equal(act(replace(s0, x_shovel=0.40), mem), [1.0, 1.0, 1.0])   # 0.54 - 0.15: curl, boom still
    np.testing.assert_array_equal(act(replace(s0, x_shovel=0.60, phi_shovel=0.305), mem), [1.0, 1.0, -1.0])  # curled
    assert mem == {}                                                                      # no lift yet
    # half a control period ahead (LATE_LOOKAHEAD_S 0.05 s): at 0.815 m and 0.3 m/s the tip reaches 0.83 > x_lift
    ahead = {}
    act(replace(s0, x_shovel=0.815, phi_shovel=0.31, v_x=0.3), ahead)
    assert ahead == {"lift": True, "late": True}
    act(replace(s0, x_shovel=0.815, phi_shovel=0.31, v_x=0.0), mem)                       # standing: not yet
    assert mem == {}
    # the tip reaches x_lift = 0.829 without a stall: a late lift, lift and curl; the wheels stop once
    # x > x_max - (0.04 + 0.45 (z_min - z)): near the floor (z 0.02) 0.88 - 0.1885 = 0.6915, so at 0.83 in place
    late = replace(s0, x_shovel=0.83, phi_shovel=0.31)
    np.testing.assert_array_equal(act(late, mem), [-1.0, -1.0, 1.0])
    assert mem == {"lift": True, "late": True}
    np.testing.assert_array_equal(act(replace(late, x_shovel=0.68), mem), [1.0, -1.0, 1.0])   # short of it: full
    # the band narrows as the tip rises: at z = 0.15, 0.88 - 0.13 = 0.75
    margin = LATE_STOP_0 + LATE_STOP_K * (z_min - 0.15)
    assert margin == pytest.approx(0.13)
    np.testing.assert_array_equal(act(replace(late, x_shovel=0.74, z_shovel=0.15), mem), [1.0, -1.0, 1.0])
    np.testing.assert_array_equal(act(replace(late, x_shovel=0.76, z_shovel=0.15), mem), [-1.0, -1.0, 1.0])
    np.testing.assert_array_equal(act(replace(late, x_shovel=0.87, z_shovel=0.36), mem), [1.0, -1.0, 1.0])  # above z_min
    # the memory holds: a later state short of x_lift still lifts
    np.testing.assert_array_equal(act(replace(late, x_shovel=0.70, z_shovel=0.10), mem), [1.0, -1.0, 1.0])
    # a stall (drift) starts the lift as before: crowd, the 0.2 m end-zone stop, pre-curl first
    mem2 = {}
    stall = replace(s0, x_shovel=0.45, phi_shovel=0.1, drift=True)
    np.testing.assert_array_equal(act(stall, mem2), [2 * crowd - 1, 1.0, 1.0])            # curl to pre_curl first
    assert mem2 == {"lift": True, "late": False}
    lifting = replace(stall, drift=False, phi_shovel=0.35)
    np.testing.assert_array_equal(act(replace(lifting, x_shovel=0.60, z_shovel=0.1), mem2), [2 * crowd - 1, -1.0, 1.0])
    np.testing.assert_array_equal(act(replace(lifting, x_shovel=0.69, z_shovel=0.1), mem2), [-1.0, -1.0, 1.0])  # 0.88 - 0.2
    # the pitch passing push_curl + 0.02 starts the lift too (a bucket that curled on)
    mem3 = {}
    act(replace(s0, x_shovel=0.5, phi_shovel=0.33), mem3)
    assert mem3 == {"lift": True, "late": False}


def test_the_teacher_setting_picks_the_maneuver(cfg, params):
    """The level push (demo_push_curl = demo_late_lift = 0, every shipped file) is scripted_action
    exactly; with either set, push_curl_action, which refuses to run without the attempt's memory.
    The policy node's core keeps that memory per attempt and empties it at each reset."""
    from dataclasses import replace

    from lhd_loading_ros.policy.maneuver import scripted_action
    from lhd_loading_ros.policy.teacher import teacher_action
    from lhd_loading_ros.task.state import LhdState

    s = LhdState(x_shovel=0.6, y_shovel=0.0, z_shovel=0.02, phi_shovel=0.0, v_x=0.3, drift=False, phi_boom=0.0,
                 dphi_boom=0.0, phi_bucket=0.0, dphi_bucket=0.0)
    level = TeacherSetting(0.625, 0.3, True, 0.2)
    assert not level.pushes_curled
    np.testing.assert_array_equal(teacher_action(s, ZONE, level),
                                  scripted_action(s, ZONE[0], crowd=0.625, pre_curl=0.3, lift_on_drift=True,
                                                  end_zone=(ZONE[1], ZONE[2]), end_zone_stop=0.2))
    curled = replace(level, push_curl=0.3, late_lift=0.85)
    with pytest.raises(ValueError, match="needs the attempt's memory"):
        teacher_action(s, ZONE, curled)
    mem = {}     # 0.6 m: past x_min - 0.15 = 0.37, short of x_lift = 0.52 + 0.85 x 0.33 = 0.80: curl while pushing
    np.testing.assert_array_equal(teacher_action(s, ZONE, curled, mem), [1.0, 1.0, 1.0])
    assert mem == {}
    t = dict(yaml.safe_load((ROOT / "config" / "lhd_params.yaml").read_text())["training"],
             demo_push_curl=0.3, demo_late_lift=0.85)
    assert TeacherSetting.from_config({"training": t}) == curled
    core = TeacherCore(curled, params, ArmKinematics.from_config(cfg))
    core.memory["lift"] = True
    core.reset()
    assert core.memory == {}


def test_confirm_drift_by_hand():
    """policy/teacher.confirm_drift, the count the node's teacher and the training's demonstrations share:
    flags up, up, down, up, up, up with confirm 3 pass only the last; a sample already counted (fresh False)
    does not count again; confirm 1 passes every flag; a non-whole or < 1 confirm is refused."""
    from lhd_loading_ros.policy.teacher import confirm_drift
    from lhd_loading_ros.task.state import LhdState

    base = LhdState(x_shovel=0.5, y_shovel=0.0, z_shovel=0.05, phi_shovel=0.0, v_x=0.3, drift=False, phi_boom=0.0,
                    dphi_boom=0.0, phi_bucket=0.0, dphi_bucket=0.0)
    run, passed, runs = 0, [], []
    for up in (True, True, False, True, True, True):
        s = base if not up else dataclasses.replace(base, drift=True, drift_front=True)
        out, run = confirm_drift(s, run, 3)
        passed.append(out.drift)
        runs.append(run)
        if not out.drift:
            assert not out.drift_front and not out.drift_rear
    assert passed == [False, False, False, False, False, True] and runs == [1, 2, 0, 1, 2, 3]
    up = dataclasses.replace(base, drift=True, drift_rear=True)
    assert confirm_drift(up, 2, 3, fresh=False) == (dataclasses.replace(up, drift=False, drift_rear=False), 2)
    assert confirm_drift(up, 0, 1) == (up, 1)
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="drift_confirm"):
            confirm_drift(up, 0, bad)
