"""The attempt life cycle of the real machine (task/attempt.py) with hand-built inputs and a
fake clock: each preflight problem, each end condition, drift %, the final pitch, SL after
weighing, the load-cell window."""
import math

import numpy as np

import pytest

from lhd_loading_ros.task import attempt as attempt_module
from lhd_loading_ros.task.attempt import ERROR, OK, STALE, STALL_S, WARN, HwStatus, Settings, Supervisor
from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.zones import Zones

# Hand geometry of the scaled LHD (config/lhd_params.yaml, machine): attack pose (boom = bucket
# = 0), base_link = rear axle centre at height r = 0.137 m. Tip ahead of the rear axle:
# wheelbase 0.80 + boom pivot ahead of the front axle 0.15 + boom reach sqrt(0.55^2 - (0.42 -
# 0.12)^2) + tip ahead of the hinge 0.30; tip height 0.005 (floor gap) + 0.01 (plate) = 0.015.
R_WHEEL = 0.137
TIP_AHEAD = 0.80 + 0.15 + math.sqrt(0.55 ** 2 - 0.30 ** 2) + 0.30      # 1.710977 m
TIP_Z = 0.015
# With the boom lifted by b (rad, negative lifts) and the bucket curled by k, about the boom
# pivot (0.95 m ahead of the rear axle, 0.42 m high): hinge offset (reach, -0.30), tip offset
# from the hinge (0.30, -0.105) (tip ahead of the hinge; plate top 0.105 below the hinge),
# rotated by R_y: (x, z) -> (c x + s z, -s x + c z).


def rot(a, x, z):
    c, s = math.cos(a), math.sin(a)
    return c * x + s * z, -s * x + c * z


def tip_hand(base_x, boom, bucket):
    hx, hz = rot(boom, math.sqrt(0.55 ** 2 - 0.30 ** 2), -0.30)
    tx, tz = rot(boom - bucket, 0.30, -0.105)
    return base_x + 0.95 + hx + tx, 0.42 + hz + tz


ZONES = Zones(x_min=0.5, x_max=1.0, z_min=0.35, x_cutoff=1.5, x_obs_start=-0.1, x_obs_end=1.1, y_half=0.2,
              z_top=0.4)
START_X = -TIP_AHEAD                      # tip at x = 0 (permitted), attack pose
LIFT = (-0.5, 0.3)                        # boom, bucket: pitch 0.8 rad = 45.8 deg > 40 deg
END_X = 0.7 - (tip_hand(0.0, *LIFT)[0])   # tip at x = 0.7, z ~ 0.52: end zone
DEG = math.radians


@pytest.fixture
def kin(cfg):
    return ArmKinematics.from_config(cfg)


def settings(**kw):
    base = dict(slope_range_deg=(15.0, 30.0), slope_source="test range", phi_thresh=DEG(40.0), control_dt=0.1,
                attempt_timeout=10.0, arm_delay=1.0, input_timeout=0.5, hw_status_timeout=0.5, mass_settle_s=1.0)
    base.update(kw)
    return Settings(**base)


class Rig:
    """A supervisor and a fake clock; `feed(t)` gives every 10 Hz input at time t."""

    def __init__(self, kin, **kw):
        self.sv = Supervisor(settings(**kw), kin, "rld", "homogeneous")
        self.t = 100.0
        self.base_x, self.boom, self.bucket, self.v_x = START_X, 0.0, 0.0, 0.0
        self.front = self.rear = False
        self.hw = HwStatus(OK, False, "drive enabled")
        self.vel = 0.0
        self.base_y, self.yaw = 0.0, 0.0  # placement: base_link off the pile's axis (m), heading (rad)
        self.imu = None                   # (w, x, y, z) of an IMU on the rear frame, when fed

    def feed(self, t=None, joints=True, odom=True, drift=True, hw=True):
        if t is not None:
            self.t = t
        i = self.sv.inputs
        if joints:
            i.put("joints", {"boom": (self.boom, self.vel), "bucket": (self.bucket, self.vel),
                             "wheel_fl": (0.0, self.vel)}, self.t)
        if odom:
            i.put("odom", ((self.base_x, self.base_y, R_WHEEL),
                           (math.cos(self.yaw / 2), 0.0, 0.0, math.sin(self.yaw / 2)), self.v_x), self.t)
        if drift:
            i.put("drift_front", self.front, self.t)
            i.put("drift_rear", self.rear, self.t)
        if hw:
            i.put("hw", self.hw, self.t)
        if self.imu is not None:
            i.put("imu", self.imu, self.t)
        return self

    def ready(self, slope_deg=20.0):
        self.sv.inputs.put("slope", DEG(slope_deg), self.t)
        self.sv.inputs.put("zones", ZONES, self.t)
        return self.feed()

    def step(self, dt, **kw):
        """Advance the clock by dt in 20 ms ticks with fresh inputs (the 50 Hz loop); times on
        a millisecond grid, so that 1.0 s after 100.0 is exactly 101.0."""
        ms0 = round(self.t * 1000)
        ms_end = ms0 + round(dt * 1000)
        ms = ms0
        while ms < ms_end:
            ms = min(ms + 20, ms_end)
            self.t = ms / 1000
            self.feed(**kw)
            self.sv.update(self.t)
        return self.sv.state

    def arm(self):
        ok, msg = self.sv.arm(self.t, "2025-01-01T00:00:00Z")
        assert ok, msg
        return msg


def test_the_tip_is_computed_with_the_policys_kinematics(kin):
    r = Rig(kin).ready()
    r.sv.update(r.t)
    assert r.sv.tip.x_shovel == pytest.approx(0.0, abs=1e-4) and r.sv.tip.z_shovel == pytest.approx(TIP_Z, abs=1e-4)
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    r.feed()
    r.sv.update(r.t)
    x, z = tip_hand(END_X, *LIFT)
    assert (x, z) == (pytest.approx(0.7, abs=1e-9), pytest.approx(0.5198, abs=1e-3))
    assert r.sv.tip.x_shovel == pytest.approx(x, abs=1e-4) and r.sv.tip.z_shovel == pytest.approx(z, abs=1e-4)
    assert r.sv.tip.phi_shovel == pytest.approx(0.8, abs=1e-9)     # pitch = -boom + bucket


# ------------------------------------------------------------------ preflight
def test_nothing_received_lists_every_missing_input(kin):
    sv = Supervisor(settings(), kin, "rld", "homogeneous")
    assert sv.state == "idle"
    problems = sv.preflight(0.0)
    text = "\n".join(problems)
    for what in ("no joint states received", "no odometry v_x received", "no front drift flag received",
                 "no rear drift flag received", "no bridge status received (/lhd/hw/status)",
                 "no pile slope received (/lhd/pile/slope", "no pile zones received (/lhd/pile/zones"):
        assert what in text, text
    assert len(problems) == 7, problems
    ok, msg = sv.arm(0.0, "x")
    assert not ok and msg.startswith("not armed: ") and sv.state == "idle" and sv.attempt is None


def test_ready_inputs_pass_the_preflight(kin):
    r = Rig(kin).ready()
    assert r.sv.preflight(r.t) == []


@pytest.mark.parametrize("case, expected", [
    ("stale_joints", "joint states 0.60 s old (timeout 0.5 s; /lhd/joint_states, the bridge)"),
    ("stale_odom", "odometry v_x 0.60 s old (timeout 0.5 s; /lhd/odom, the ArUco node)"),
    ("stale_drift", "front drift flag 0.60 s old (timeout 0.5 s; /lhd/wheel_drift/front"),
    ("stale_hw", "bridge status 0.60 s old (timeout 0.5 s; /lhd/hw/status)"),
    ("nan_boom", "joint 'boom' is not finite"),
    ("no_bucket", "joint states have no 'bucket' joint"),
    ("nan_vx", "odometry v_x is not finite"),
    ("zero_quat", "odometry pose is not finite"),
    ("slope_high", "pile slope 35.0 deg is outside the controller's range [15, 30] deg (test range)"),
    ("slope_low", "pile slope 12.0 deg is outside the controller's range [15, 30] deg"),
    ("slope_nan", "pile slope is not a finite number"),
    ("zones_bad", "pile zones invalid (/lhd/pile/zones): zones: x_min 1 must be below x_max 0.5"),
    ("hw_error", "bridge reports ERROR: serial link lost"),
    ("hw_stale", "bridge reports STALE: no sensor frame from the device for 0.7 s"),
    ("hw_estop", "emergency stop pressed on the device (bridge status): release it first"),
    ("estop_topic", "emergency stop engaged (/lhd/estop is true): release it first"),
    ("tip_in_end_zone", "bucket tip already in the end zone (x 0.700"),
    ("tip_restricted", "bucket tip in the restricted zone (x 1.211"),
])
def test_each_preflight_problem_is_named(kin, case, expected):
    r = Rig(kin).ready()
    i = r.sv.inputs
    t = r.t
    if case.startswith("stale_"):
        name = {"stale_joints": "joints", "stale_odom": "odom", "stale_drift": "drift_front", "stale_hw": "hw"}[case]
        r.feed(t + 0.6)
        i.arrival[name] = t           # that one input last came 0.6 s ago
        t = r.t
    elif case == "nan_boom":
        r.boom = math.nan
        r.feed()
    elif case == "no_bucket":
        i.put("joints", {"boom": (0.0, 0.0)}, t)
    elif case == "nan_vx":
        r.v_x = math.nan
        r.feed()
    elif case == "zero_quat":
        i.put("odom", ((START_X, 0.0, R_WHEEL), (0.0, 0.0, 0.0, 0.0), 0.0), t)
    elif case in ("slope_high", "slope_low", "slope_nan"):
        i.put("slope", {"slope_high": DEG(35.0), "slope_low": DEG(12.0), "slope_nan": math.nan}[case], t)
    elif case == "zones_bad":
        i.zones_error = "zones: x_min 1 must be below x_max 0.5"
    elif case == "hw_error":
        r.hw = HwStatus(ERROR, False, "serial link lost")
        r.feed()
    elif case == "hw_stale":
        r.hw = HwStatus(STALE, False, "no sensor frame from the device for 0.7 s")
        r.feed()
    elif case == "hw_estop":
        r.hw = HwStatus(ERROR, True, "emergency stop pressed on the device")
        r.feed()
    elif case == "estop_topic":
        i.estop = True
    elif case == "tip_in_end_zone":
        r.base_x, (r.boom, r.bucket) = END_X, LIFT
        r.feed()
    elif case == "tip_restricted":
        r.base_x = -0.5           # tip at x = 1.211 > min(x_obs_end 1.1, x_cutoff 1.5), on the floor
        r.feed()
    problems = r.sv.preflight(t)
    assert any(expected in p for p in problems), problems
    ok, msg = r.sv.arm(t, "x")
    assert not ok and expected in msg and r.sv.state == "idle"


@pytest.mark.parametrize("name, what", [("odom", "odometry v_x"), ("joints", "joint states"),
                                        ("drift_rear", "rear drift flag"), ("hw", "bridge status")])
def test_arming_needs_inputs_fresher_than_half_their_timeout(kin, name, what):
    """An input 0.30 s old passes the running check (0.5 s timeout) but not the arming one
    (0.5 x 0.5 = 0.25 s): armed on it, one more late message would end the attempt (lost_input)
    before it ran. 0.20 s old arms."""
    r = Rig(kin).ready()
    t = r.t
    r.feed(t + 0.30)
    r.sv.inputs.arrival[name] = t
    problems = r.sv.preflight(r.t)
    src = {"odom": "/lhd/odom, the ArUco node", "joints": "/lhd/joint_states, the bridge",
           "drift_rear": "/lhd/wheel_drift/rear, the bridge", "hw": "/lhd/hw/status"}[name]
    assert problems == [f"{what} 0.30 s old: to arm, at most 0.25 s (0.5 of its 0.5 s timeout, a margin before a "
                        f"late message ends the attempt; {src})"], problems
    ok, msg = r.sv.arm(r.t, "x")
    assert not ok and "to arm, at most 0.25 s" in msg and r.sv.state == "idle"
    # the running check keeps the whole timeout: an armed attempt is not ended by the same age
    r.feed(t + 1.0)
    r.arm()
    silent = {"odom": "odom", "joints": "joints", "drift_rear": "drift", "hw": "hw"}[name]
    r.step(0.30, **{silent: False})   # every input but that one, 50 Hz ticks (no pause of the caller)
    assert r.sv.state == "armed", r.sv.attempt.reason
    r.step(0.20, **{silent: False})   # to 0.50 s old: not past the timeout yet
    assert r.sv.state == "armed", r.sv.attempt.reason
    r.step(0.02, **{silent: False})   # 0.52 s: past it
    assert r.sv.state == "lost_input" and f"{what} 0.52 s old (timeout 0.5 s" in r.sv.attempt.reason
    # 0.20 s old: armed
    r2 = Rig(kin).ready()
    t = r2.t
    r2.feed(t + 0.20)
    r2.sv.inputs.arrival[name] = t
    assert r2.sv.preflight(r2.t) == []


def test_arm_fresh_fraction_is_checked(kin):
    for bad in (0.0, 1.5, math.nan):
        with pytest.raises(ValueError, match="arm_fresh_fraction"):
            settings(arm_fresh_fraction=bad)
    r = Rig(kin, arm_fresh_fraction=1.0).ready()      # 1: the running timeout alone, as before
    t = r.t
    r.feed(t + 0.45)
    r.sv.inputs.arrival["odom"] = t
    assert r.sv.preflight(r.t) == []


def test_a_slope_at_the_range_end_in_radians_is_inside(kin):
    r = Rig(kin).ready(slope_deg=30.0)
    assert r.sv.preflight(r.t) == []


def test_a_hw_warning_does_not_block(kin):
    r = Rig(kin)
    r.hw = HwStatus(WARN, False, "device watchdog holds the machine stopped")
    r.ready()
    assert r.sv.preflight(r.t) == []


# ------------------------------------------------------------------ life cycle and end conditions
def test_arm_delay_then_running_then_success_in_the_end_zone(kin):
    r = Rig(kin).ready()
    msg = r.arm()
    assert r.sv.state == "armed" and "attempt 1 armed, running in 1 s" in msg and "slope 20.0 deg" in msg
    assert r.step(0.98) == "armed"
    assert r.step(0.02) == "running"
    t_run = r.t
    assert r.sv.arm(r.t, "x")[0] is False                      # no second arming while live
    assert r.step(1.0) == "running"
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    r.feed(r.t + 0.01)
    assert r.sv.update(r.t) is False and r.sv.state == "running"     # in the end zone mid-period
    r.feed(t_run + 1.1)                                              # the period's end: judged
    assert r.sv.update(r.t) is True and r.sv.state == "success"
    row = r.sv.attempt.row()
    assert row.elapsed_s == pytest.approx(r.t - t_run) and row.elapsed_s == pytest.approx(1.1)
    assert row.phi_final_deg == pytest.approx(math.degrees(0.8), abs=0.005)     # the record's 0.01 deg
    assert row.reason == "bucket tip reached the end zone"
    assert row.success is None and row.success_level is None and row.mass_kg is None      # until weighed
    v = r.sv.status_values(r.t)
    assert v["state"] == "success" and v["episode"] == "1" and v["loaded_mass"] == "nan"
    assert v["phi_final_deg"] == "45.84" and "success" not in v and v["bag"] == "bags/attempt_0001"


def test_end_zone_is_judged_at_the_end_of_each_control_period_as_in_the_task(kin):
    """The task (the environment the controllers were trained in) ends an episode when the tip
    is in the end zone at the end of a 0.1 s step, and the state there is the final one: a tip
    that enters at 0.23 s is judged at 0.3 s, with the pitch it has then (the bucket went on
    curling). The restricted zone (a safety end) is judged at once, mid-period."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    t0 = r.t
    assert r.step(0.22) == "running"
    r.base_x, (r.boom, r.bucket) = END_X, (LIFT[0], LIFT[1] - 0.05)     # pitch 0.75 rad
    r.feed(t0 + 0.23)
    r.sv.update(r.t)
    assert r.sv.state == "running"
    r.bucket = LIFT[1]                                                  # curled on to 0.8 rad
    r.feed(t0 + 0.29)
    r.sv.update(r.t)
    assert r.sv.state == "running"
    r.feed(t0 + 0.30)
    r.sv.update(r.t)
    assert r.sv.state == "success"
    row = r.sv.attempt.row()
    assert row.elapsed_s == pytest.approx(0.30) and row.phi_final_deg == pytest.approx(math.degrees(0.8), abs=0.005)
    # end_check_period 0: judged on the update the tip enters, with the pitch it has then
    r = Rig(kin, arm_delay=0.0, end_check_period=0.0).ready()
    r.arm()
    t0 = r.t
    r.step(0.22)
    r.base_x, (r.boom, r.bucket) = END_X, (LIFT[0], LIFT[1] - 0.05)
    r.feed(t0 + 0.23)
    r.sv.update(r.t)
    assert r.sv.state == "success"
    row = r.sv.attempt.row()
    assert row.elapsed_s == pytest.approx(0.23) and row.phi_final_deg == pytest.approx(math.degrees(0.75), abs=0.005)
    # the restricted zone mid-period: at once
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    t0 = r.t
    r.step(0.22)
    r.base_x = -0.5
    r.feed(t0 + 0.23)
    r.sv.update(r.t)
    assert r.sv.state == "failure" and r.sv.attempt.row().elapsed_s == pytest.approx(0.23)
    with pytest.raises(ValueError, match="end_check_period = -0.1: expected seconds >= 0"):
        settings(end_check_period=-0.1)
    # a period longer than the attempt: the tip in the end zone at the timeout is a success
    r = Rig(kin, arm_delay=0.0, end_check_period=5.0, attempt_timeout=3.0).ready()
    r.arm()
    t0 = r.t
    r.step(1.0)
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    assert r.step(1.98) == "running"
    r.feed(t0 + 3.0)
    r.sv.update(r.t)
    assert r.sv.state == "success" and r.sv.attempt.row().elapsed_s == pytest.approx(3.0)


def test_an_attempt_whose_zones_changed_or_whose_tip_moved_while_armed_does_not_start(kin):
    """At the end of the arm delay the supervisor checks the zones it now hears against the
    zones frozen at arming (another pile estimate republished meanwhile: the twin's fault 6),
    and the tip against the frozen zones. Either ends the attempt as aborted with the reason,
    before the controller may move; small changes (under 2 cm) and a still machine start."""
    from dataclasses import replace
    r = Rig(kin).ready()
    r.arm()
    r.sv.inputs.put("zones", replace(ZONES, x_max=0.85), r.t + 0.5)         # a new pile's zones
    assert r.step(0.98) == "armed"
    assert r.step(0.02) == "aborted"
    row = r.sv.attempt.row()
    assert row.reason.startswith("not started: the pile zones changed while armed (x_max 1.000 -> 0.850 m)")
    assert row.success is False and row.elapsed_s == 0.0
    # the machine moved during the delay: its tip now in the restricted zone of the frozen zones
    r = Rig(kin).ready()
    r.arm()
    r.step(0.5)
    r.base_x = -0.5
    assert r.step(0.5) == "aborted"
    assert "not started: the bucket tip is in the restricted zone (x " in r.sv.attempt.row().reason
    # new zones, then an invalid message: not started either (the last valid zones are compared,
    # and invalid zones fail the start as they fail the preflight)
    r = Rig(kin).ready()
    r.arm()
    r.sv.inputs.put("zones", replace(ZONES, x_max=0.85), r.t + 0.3)
    r.sv.inputs.zones_error = "8 values expected, got 3"
    assert r.step(1.0) == "aborted"
    assert "the pile zones became invalid while armed" in r.sv.attempt.row().reason
    r.sv.inputs.put("zones", ZONES, r.t)                                  # a valid message clears it
    # a 1 cm re-estimate (below the end-zone node's 2 cm republishing threshold) is the same pile
    r = Rig(kin).ready()
    r.arm()
    r.sv.inputs.put("zones", replace(ZONES, x_max=1.01, x_min=0.49), r.t + 0.5)
    assert r.step(1.0) == "running"
    assert r.sv.attempt.zones == ZONES                                     # still arming's
    # zones_tolerance: a 3 cm re-estimate (a rough face's median moving) aborts at the default 2 cm
    # and starts at 5 cm; 6 cm aborts at 5 cm
    for tol, dx, end in ((0.02, 0.03, "aborted"), (0.05, 0.03, "running"), (0.05, 0.06, "aborted")):
        r = Rig(kin, zones_tolerance=tol).ready()
        r.arm()
        r.sv.inputs.put("zones", replace(ZONES, x_cutoff=ZONES.x_cutoff + dx), r.t + 0.5)
        assert r.step(1.0) == end, (tol, dx)
    with pytest.raises(ValueError, match="zones_tolerance = 0.0: expected metres in"):
        settings(zones_tolerance=0.0)


def test_restricted_zone_is_a_failure_known_without_weighing(kin):
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    assert r.sv.state == "running"
    r.base_x = -0.5
    r.feed(r.t + 0.02)
    r.sv.update(r.t)
    assert r.sv.state == "failure"
    row = r.sv.attempt.row()
    assert row.success is False and row.reason == "bucket tip entered the restricted zone"
    assert r.sv.status_values(r.t)["success"] == "False"


def test_timeout_after_exactly_attempt_timeout(kin):
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    t0 = r.t
    assert r.step(9.98) == "running"
    r.feed(t0 + 9.999)
    r.sv.update(r.t)
    assert r.sv.state == "running"
    r.feed(t0 + 10.0)
    r.sv.update(r.t)
    assert r.sv.state == "timeout"
    assert r.sv.attempt.row().elapsed_s == pytest.approx(10.0)
    assert r.sv.attempt.reason == "attempt_timeout 10 s passed"


def test_estop_topic_and_device_estop_end_the_attempt(kin):
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.5)
    r.sv.inputs.estop = True
    r.sv.update(r.t)
    assert r.sv.state == "estop" and r.sv.attempt.reason == "emergency stop engaged (/lhd/estop is true)"
    assert r.sv.attempt.row().success is False
    # released: the next attempt; the device's own button
    r.sv.inputs.estop = False
    r.arm()
    assert r.sv.attempt.number == 2
    r.hw = HwStatus(ERROR, True, "emergency stop pressed on the device")
    r.step(0.02)
    assert r.sv.state == "estop" and "pressed on the device" in r.sv.attempt.reason


def test_estop_while_armed_ends_before_running(kin):
    r = Rig(kin).ready()
    r.arm()
    r.sv.inputs.estop = True
    r.step(0.02)
    assert r.sv.state == "estop" and r.sv.attempt.running_at is None and r.sv.attempt.row().elapsed_s == 0.0


@pytest.mark.parametrize("silent", ["joints", "odom", "drift", "hw"])
def test_a_silent_input_is_lost_input_after_input_timeout(kin, silent):
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    t_last = r.t
    kw = {silent: False}
    r.step(0.48, **kw)                         # 0.48 s old: still running
    assert r.sv.state == "running"
    r.step(0.06, **kw)                         # lost at the first tick older than 0.5 s
    assert r.sv.state == "lost_input"
    assert 0.5 < r.sv.attempt.ended_at - t_last <= 0.52 + 1e-9
    assert "s old (timeout 0.5 s;" in r.sv.attempt.reason


INPUTS = ("joints", "odom", "drift", "hw")


def _pause(r, seconds):
    """The caller's process does not run for `seconds`: no update, nothing taken."""
    r.t = round(r.t + seconds, 3)


def _take(r, name):
    """One subscription callback: its queued message taken, then the node's check."""
    r.feed(**{k: k == name for k in INPUTS})
    r.sv.update(r.t)


@pytest.mark.parametrize("timer_first", [True, False])
def test_a_paused_caller_does_not_take_queued_inputs_for_silence(kin, timer_first):
    """The node's process pauses 0.8 s (CPU starvation): every input kept arriving but waits in
    its queue. On waking, the executor runs the 50 Hz check before it takes them (timers first),
    or, when the timer was not due yet in that pass, a callback takes its message first and
    checks. Either way the first check sees the other inputs 0.8 s old; neither it nor the
    checks after each queued input taken one at a time may end the attempt."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    _pause(r, 0.8)
    if timer_first:
        r.sv.update(r.t)                       # nothing taken yet, all 0.8 s old
        assert r.sv.state == "running", r.sv.attempt.reason
        assert r.sv.held_inputs(r.t) == ["joints", "odom", "drift_front", "drift_rear", "hw"]
    for name in INPUTS:
        _take(r, name)
        assert r.sv.state == "running", (name, r.sv.attempt.reason)
    assert r.sv.held_inputs(r.t) == []
    assert r.step(1.0) == "running"            # and on, as before the pause


def test_a_second_short_pause_before_the_queue_is_taken(kin):
    """Pause 1.0 s, the timer's check, then the process is preempted again for 0.15 s before its
    callbacks take the queue, and the callbacks come one per 50 Hz tick with the timer between
    them: the first pause still counts for the inputs taken before it (a later, shorter pause
    does not replace it)."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    _pause(r, 1.0)
    r.sv.update(r.t)
    _pause(r, 0.15)
    for name in INPUTS:
        _take(r, name)
        assert r.sv.state == "running", (name, r.sv.attempt.reason)
        r.t = round(r.t + 0.04, 3)             # slow takes, timer ticks between them
        r.sv.update(r.t)
        assert r.sv.state == "running", (name, r.sv.attempt.reason)
    assert r.step(1.0) == "running"


@pytest.mark.parametrize("silent", ["joints", "odom", "drift", "hw"])
def test_an_input_silent_across_a_pause_is_still_found(kin, silent):
    """The input really stopped when the pause began: by hand, its age leaves out the pause's
    0.7 s beyond STALL_S, so it is lost 0.5 - 0.1 = 0.4 s of running after the pause (0.5 s of
    the caller's running time in all), and the reason gives its real age and the pause."""
    assert STALL_S == 0.1
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    _pause(r, 0.8)
    r.sv.update(r.t)
    t_resume = r.t
    for name in INPUTS:
        if name != silent:
            _take(r, name)
    assert r.sv.state == "running"
    r.step(0.38, **{silent: False})            # 0.38 s of running: 0.48 s counted
    assert r.sv.state == "running"
    r.step(0.04, **{silent: False})            # 0.40 (the boundary tick) or 0.42 s
    assert r.sv.state == "lost_input"
    assert t_resume + 0.40 - 1e-9 <= r.sv.attempt.ended_at <= t_resume + 0.42 + 1e-9
    assert "s old (timeout 0.5 s, 0.70 s of it a pause of the supervisor not counted;" in r.sv.attempt.reason


def _silent_joints_found_after(kin, gap):
    """Checks only every `gap` s, each the timer's first (after the pause), then the callbacks
    of the inputs that still come; the joint states stop at d. Seconds from d to lost_input."""
    r = Rig(kin, arm_delay=0.0, attempt_timeout=60.0).ready()
    r.arm()
    r.step(0.3)
    d = r.t
    for k in range(1, 10):
        r.t = round(d + gap * k, 3)
        r.sv.update(r.t)                       # the timer, first in the pass
        if r.sv.state == "running":
            for name in ("odom", "drift", "hw"):
                _take(r, name)
        if r.sv.state != "running":
            break
    assert r.sv.state == "lost_input" and "joint states" in r.sv.attempt.reason, r.sv.attempt.reason
    return r.sv.attempt.ended_at - d


@pytest.mark.parametrize("gap, found, without", [(0.25, 0.75, 0.75), (0.3, 0.9, 0.6), (0.45, 0.9, 0.9)])
def test_a_caller_paused_all_the_time_still_finds_a_silent_input(kin, monkeypatch, gap, found, without):
    """Every gap is a pause of gap - 0.1 s beyond STALL_S that began after the last joint state,
    so by hand the check at d + gap k counts an age of gap k - (gap - 0.1), past 0.5 s first at
    k = 3, 3, 2: found at d + 0.75, 0.9, 0.9; without the allowance (STALL_S patched to infinity)
    at the first check past 0.5 s real age: 0.75, 0.6, 0.9. At most one gap later."""
    assert STALL_S == 0.1
    assert _silent_joints_found_after(kin, gap) == pytest.approx(found)
    monkeypatch.setattr(attempt_module, "STALL_S", math.inf)
    assert _silent_joints_found_after(kin, gap) == pytest.approx(without)


def test_a_pause_does_not_delay_a_device_estop_or_the_timeout(kin):
    """Only the inputs' ages leave out a pause: the device's e-stop in a queued bridge status ends
    the attempt as soon as it is taken (not lost_input), and the attempt's own timeout counts the
    paused time."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    _pause(r, 0.8)
    r.sv.update(r.t)
    r.hw = HwStatus(WARN, True, "emergency stop pressed")
    _take(r, "hw")
    assert r.sv.state == "estop" and r.sv.attempt.reason == "emergency stop pressed on the device (bridge status)"
    r2 = Rig(kin, arm_delay=0.0, attempt_timeout=1.0).ready()
    r2.arm()
    t_run = r2.t
    r2.step(0.3)
    _pause(r2, 0.9)                            # paused across the timeout
    r2.sv.update(r2.t)
    assert r2.sv.state == "timeout" and r2.sv.attempt.ended_at == pytest.approx(t_run + 1.2)


def test_a_pause_across_the_arm_delay_waits_for_the_queued_zones(kin):
    """Armed, the arm delay ends inside a pause, and the end-zone node republished other zones
    meanwhile (queued): the attempt does not start on the timer's check after the pause, but once
    the queue is taken, where the moved zones abort it as without a pause."""
    r = Rig(kin, arm_delay=1.0).ready()
    r.arm()
    assert r.step(0.5) == "armed"
    _pause(r, 0.8)
    r.sv.update(r.t)                           # 1.3 s after arming, inputs held: no start
    assert r.sv.state == "armed"
    moved = Zones(**{**{f: getattr(ZONES, f) for f in ("x_min", "x_max", "z_min", "x_cutoff", "x_obs_start",
                                                      "x_obs_end", "y_half", "z_top")}, "x_max": 0.85})
    r.sv.inputs.put("zones", moved, r.t)
    for name in INPUTS:
        _take(r, name)
    assert r.sv.state == "aborted" and "the pile zones changed while armed (x_max 1.000 -> 0.850 m)" in \
        r.sv.attempt.reason


def test_success_after_a_pause_is_judged_on_the_present_tip(kin):
    """The tip entered the end zone mid-period, then the caller paused 2 s: the check after the
    pause does not judge the end zone on the tip from before it; the success comes once the
    queued joint states and odometry are taken, with the tip they give (the bucket curled on)."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    t_run = r.t
    r.step(0.3)
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    r.feed(r.t + 0.05)
    r.sv.update(r.t)
    assert r.sv.state == "running"             # mid-period
    _pause(r, 2.0)
    r.sv.update(r.t)
    assert r.sv.state == "running"             # no verdict on a 2 s old tip
    r.bucket = LIFT[1] + 0.1
    for name in INPUTS:
        _take(r, name)
    assert r.sv.state == "success"
    row = r.sv.attempt.row()
    assert row.elapsed_s == pytest.approx(r.t - t_run)
    assert row.phi_final_deg == pytest.approx(math.degrees(LIFT[1] + 0.1 - LIFT[0]), abs=0.005)


def test_inputs_taken_after_the_last_check_count_a_pause_that_follows(kin):
    """The drift flags taken 3 ms after the last check, then a 0.8 s pause: the pause began after
    them too (it starts at the later of the last check and the last input taken), so the timer's
    check after it does not call them lost. And a pause longer than STALL_MEMORY_S is kept."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    r.feed(round(r.t + 0.003, 3), joints=False, odom=False, hw=False)   # drift flags only, no check
    _pause(r, 0.8)
    r.sv.update(r.t)
    assert r.sv.state == "running", r.sv.attempt.reason
    for name in INPUTS:
        _take(r, name)
    _pause(r, 40.0)                            # beyond STALL_MEMORY_S (30 s)
    r.sv.update(r.t)
    assert r.sv.state == "timeout" and r.sv.attempt.reason == "attempt_timeout 10 s passed"   # not lost_input


def test_a_short_pause_across_the_arm_delay_waits_for_the_queue(kin):
    """A 0.45 s pause (under input_timeout: nothing is past its timeout) that spans the end of the
    arm delay: the timer's check after it does not start the attempt on the state from before the
    pause; the republished zones taken from the queue abort it."""
    r = Rig(kin, arm_delay=1.0).ready()
    r.arm()
    assert r.step(0.7) == "armed"
    _pause(r, 0.45)
    r.sv.update(r.t)
    assert r.sv.state == "armed" and r.sv.held_inputs(r.t) == ["joints", "odom", "drift_front", "drift_rear", "hw"]
    r.sv.inputs.put("zones", Zones(**{**ZONES.__dict__, "x_max": 0.85}), r.t)
    for name in INPUTS:
        _take(r, name)
    assert r.sv.state == "aborted" and "x_max 1.000 -> 0.850 m" in r.sv.attempt.reason


def test_a_short_pause_defers_the_end_zone_to_the_queued_tip(kin):
    """The tip entered the end zone mid-period, then a 0.45 s pause: no success on the tip from
    before it; the success comes with the queued messages' tip."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    r.feed(r.t + 0.05)
    r.sv.update(r.t)
    _pause(r, 0.45)
    r.sv.update(r.t)
    assert r.sv.state == "running"
    r.bucket = LIFT[1] + 0.1
    for name in INPUTS:
        _take(r, name)
    assert r.sv.state == "success"
    assert r.sv.attempt.row().phi_final_deg == pytest.approx(math.degrees(LIFT[1] + 0.1 - LIFT[0]), abs=0.005)


def test_the_restricted_zone_is_judged_while_waiting_for_the_queue(kin):
    """After a pause, the odometry taken first puts the tip beyond the observation zone while the
    other inputs are still queued: a safety end, judged at once (failure), not deferred."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    _pause(r, 0.8)
    r.sv.update(r.t)
    r.base_x = START_X + 1.2                   # tip at x = 1.2 m, beyond x_obs_end 1.1 m
    _take(r, "odom")
    assert r.sv.held_inputs(r.t) != []
    assert r.sv.state == "failure" and r.sv.attempt.reason == "bucket tip entered the restricted zone"


def test_arming_after_a_pause_judges_real_ages(kin):
    """Idle, the caller paused 0.3 s: arming right after it (before the queue is taken) is refused
    with the inputs' real age, 0.30 s against the 0.25 s arming margin."""
    r = Rig(kin).ready()
    r.sv.update(r.t)
    _pause(r, 0.3)
    r.sv.update(r.t)
    ok, msg = r.sv.arm(r.t, "x")
    assert not ok and "joint states 0.30 s old: to arm, at most 0.25 s" in msg, msg


def test_nan_while_running_is_lost_input_not_a_zone(kin):
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.2)
    r.bucket = math.nan
    r.step(0.02)
    assert r.sv.state == "lost_input" and "joint 'bucket' is not finite" in r.sv.attempt.reason
    assert r.sv.attempt.row().phi_final_deg == pytest.approx(0.0)     # the last good tip


def test_bridge_error_while_running_is_lost_input(kin):
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.hw = HwStatus(STALE, False, "no sensor frame from the device for 0.6 s")
    r.step(0.02)
    assert r.sv.state == "lost_input" and "bridge reports STALE" in r.sv.attempt.reason


def test_the_bridges_own_watchdog_while_running_is_lost_input(kin):
    """No valid command reached the bridge for its cmd_timeout: it stopped the machine, so the
    mux (or its link) stalled; the attempt ends, not drives on afterwards."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.2)
    assert r.sv.state == "running"
    r.hw = HwStatus(WARN, False, "drive enabled", command_stale=True)
    r.step(0.02)
    assert r.sv.state == "lost_input" and r.sv.attempt.reason.startswith("the bridge took no valid command"), \
        r.sv.attempt.reason


@pytest.mark.parametrize("controller, sources, outcome", [
    # the mux selected the controller, then its source timed out: the controller stalled or died
    ("rld", ["none", "auto", "none"], "lost_input"),
    # the operator's gamepad took over an autonomous attempt
    ("rld", ["auto", "teleop"], "aborted"),
    # ... or drove it from the start, its deadman held since the arming (a review found such an
    # attempt recorded as RLD's)
    ("rld", ["teleop"], "aborted"),
    # before the controller's first command the mux sends zeros (none): not a loss
    ("rld", ["none", "none"], "running"),
    # the mux reports the e-stop: an e-stop end even when /lhd/estop itself was not heard (a volatile
    # publisher the supervisor's latched subscription does not match)
    ("tampier", ["auto", "estop"], "estop"),
    ("teleop", ["teleop", "estop"], "estop"),
    # a teleoperated attempt: the operator lets go of the deadman now and then
    ("teleop", ["teleop", "none", "teleop"], "running"),
])
def test_the_controllers_commands_stopping_while_running(kin, controller, sources, outcome):
    r = Rig(kin, arm_delay=0.0)
    r.sv = Supervisor(settings(arm_delay=0.0), kin, controller, "homogeneous")
    r.ready()
    r.arm()
    for src in sources:
        r.sv.inputs.put("mux", src, r.t)
        r.step(0.1)
    assert r.sv.state == outcome, (r.sv.state, r.sv.attempt.reason)
    if outcome == "lost_input":
        assert "the command mux's auto source timed out" in r.sv.attempt.reason
    if outcome == "aborted":
        assert r.sv.attempt.reason == "the operator took over: the command mux selected 'teleop' over the controller"
    if outcome == "estop":
        assert r.sv.attempt.reason.startswith("emergency stop engaged (the command mux reports it")


def test_a_controller_whose_commands_never_come_ends_the_attempt_after_a_second(kin):
    """The mux heard but never selecting `auto` (a controller not running, or remapped elsewhere
    than cmd/auto): until 2026-11-28 such an attempt stood still until its timeout and was recorded
    as one. Now lost_input once FIRST_COMMAND_S (1 s) of running passed without it, by hand: still
    running at 1.0 s, ended at 1.1 s. Without a mux heard (a stack without one) nothing is judged;
    a teleoperated attempt is the operator's to start."""
    from lhd_loading_ros.task.attempt import FIRST_COMMAND_S

    assert FIRST_COMMAND_S == 1.0
    for controller, mux, ends in (("rld", "none", True), ("tampier", "none", True), ("rld", None, False),
                                  ("teleop", "none", False)):
        r = Rig(kin, arm_delay=0.0)
        r.sv = Supervisor(settings(arm_delay=0.0), kin, controller, "homogeneous")
        r.ready()
        r.arm()
        r.step(0.0)
        assert r.sv.state == "running"
        t_run = r.sv.attempt.running_at
        while r.t - t_run < 1.0 - 1e-9:
            if mux is not None:
                r.sv.inputs.put("mux", mux, r.t)
            r.step(0.1)
            assert r.sv.state == "running", (controller, r.t - t_run, r.sv.attempt.reason)
        if mux is not None:
            r.sv.inputs.put("mux", mux, r.t)
        r.step(0.1)
        assert (r.sv.state == "lost_input") == ends, (controller, mux, r.sv.state)
        if ends:
            assert r.sv.attempt.reason.startswith("the controller's commands never reached the machine: the command "
                                                  "mux did not select its auto source within 1 s of running")
            assert "/lhd/cmd/auto" in r.sv.attempt.reason


def test_the_controller_of_the_attempt_not_the_label_changed_since(kin):
    """The rule follows the attempt's own controller: relabelling the node's `controller` to
    teleop mid-attempt does not switch it off."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.sv.controller = "teleop"
    r.sv.inputs.put("mux", "teleop", r.t)
    r.step(0.1)
    assert r.sv.state == "aborted"


def test_arming_is_refused_while_the_gamepad_is_selected_or_the_mux_reports_the_estop(kin):
    r = Rig(kin).ready()
    r.sv.inputs.put("mux", "teleop", r.t)
    ok, msg = r.sv.arm(r.t, "x")
    assert not ok and "the command mux has 'teleop' selected (the gamepad's deadman held?)" in msg, msg
    r.sv.inputs.put("mux", "estop", r.t)
    ok, msg = r.sv.arm(r.t, "x")
    assert not ok and "the command mux reports it" in msg and "release it first" in msg, msg
    r.sv.inputs.put("mux", "none", r.t)
    r.arm()
    t = Supervisor(settings(), kin, "teleop", "homogeneous")      # a teleop attempt: the gamepad is its controller
    r.sv = t
    r.ready()
    t.inputs.put("mux", "teleop", r.t)
    assert t.preflight(r.t) == []
    # and an autonomous controller moving a teleop-labelled attempt is not that attempt (a review, 2026-11-29)
    from dataclasses import replace

    t.s = replace(t.s, arm_delay=0.0)
    t.inputs.put("mux", "none", r.t)
    r.arm()
    r.step(0.1)
    r.sv.inputs.put("mux", "auto", r.t)
    assert r.step(0.02) == "aborted" and "an autonomous controller's commands moved a teleop attempt" in \
        r.sv.attempt.reason


def test_the_mux_left_over_from_the_last_attempt_is_not_this_attempts(kin):
    """Attempt 1 ends, the mux goes back to none; attempt 2 must see auto selected again before a
    none counts."""
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.sv.inputs.put("mux", "auto", r.t)
    r.step(0.1)
    r.sv.abort(r.t)
    r.sv.inputs.put("mux", "none", r.t)
    r.step(0.1)
    r.arm()
    r.step(0.3)
    assert r.sv.state == "running"


def test_abort_and_refusals(kin):
    r = Rig(kin).ready()
    assert r.sv.abort(r.t) == (False, "nothing to abort: no attempt yet")
    r.arm()
    ok, msg = r.sv.abort(r.t)
    assert ok and msg == "attempt 1 aborted" and r.sv.state == "aborted"
    assert r.sv.attempt.reason == "aborted by the operator (/lhd/abort)"
    assert r.sv.abort(r.t) == (False, "nothing to abort: attempt 1 already ended (aborted)")
    r.arm()                                    # an ended state goes back only through arming
    assert r.sv.state == "armed" and r.sv.attempt.number == 2


def test_numbering_continues_a_record(kin):
    sv = Supervisor(settings(), kin, "teleop", "nonhomogeneous", first_attempt=8)
    r = Rig(kin)
    r.sv = sv
    r.ready()
    r.arm()
    assert sv.attempt.number == 8 and sv.attempt.row().bag == "bags/attempt_0008"
    assert sv.attempt.row().controller == "teleop" and sv.attempt.row().material == "nonhomogeneous"


def test_zones_and_slope_are_those_of_the_arming(kin):
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    # a pile estimate republished mid-attempt (the end zone moved under the tip) is not the goal
    r.sv.inputs.put("zones", Zones(-1.0, 0.1, 0.0, 1.5, -0.1, 1.1, 0.2, 0.4), r.t)
    r.sv.inputs.put("slope", DEG(25.0), r.t)
    assert r.step(0.5) == "running"
    assert r.sv.attempt.row().slope_deg == pytest.approx(20.0)


# ------------------------------------------------------------------ figures
def test_drift_percent_over_10_hz_samples(kin):
    """2 s attempt (timeout 2 s): samples at the end of each 0.1 s period, k = 1..20. Front
    drifting until 0.55 s (samples 0.1-0.5: 5 of 20 = 25 %), rear always (100 %)."""
    r = Rig(kin, arm_delay=0.0, attempt_timeout=2.0).ready()
    r.arm()
    r.front, r.rear = True, True
    r.step(0.54)
    r.front = False
    r.step(1.46)
    assert r.sv.state == "timeout"
    row = r.sv.attempt.row()
    assert len(r.sv.attempt.front) == 20
    assert row.front_drift_pct == pytest.approx(25.0) and row.rear_drift_pct == pytest.approx(100.0)


@pytest.mark.parametrize("outcome_pose, mass, sl, success", [
    ("end", 23.4, 2, True),          # 23.4 kg >= 22, pitch 45.8 > 40 deg
    ("end", 28.0, 5, True),
    ("end", 19.9, 0, False),         # under 20 kg
    ("end_flat", 30.0, 0, False),    # pitch 30 deg: not > 40
    ("timeout", 24.5, 3, True),      # the paper: timeouts meeting both conditions are successes
    ("failure", 30.0, 0, False),     # restricted zone: failure whatever the load (pitch 0 here)
])
def test_success_level_and_success_after_weighing(kin, outcome_pose, mass, sl, success):
    r = Rig(kin, arm_delay=0.0, attempt_timeout=1.0).ready()
    r.arm()
    r.step(0.1)
    if outcome_pose == "end":
        r.base_x, (r.boom, r.bucket) = END_X, LIFT
    elif outcome_pose == "end_flat":                   # boom -0.7, bucket -0.17: pitch 0.53 rad = 30 deg
        r.boom, r.bucket = -0.7, -0.1764
        r.base_x = 0.7 - tip_hand(0.0, r.boom, r.bucket)[0]
    elif outcome_pose == "timeout":
        r.boom, r.bucket = -0.2, 0.6                   # pitch 0.8 rad, tip still low in the permitted zone
    else:
        r.base_x = -0.5
    r.step(1.0)
    assert r.sv.state in ("success", "timeout", "failure")
    with pytest.raises(ValueError, match="not a finite number"):
        r.sv.set_mass(math.nan)
    with pytest.raises(ValueError, match="negative"):
        r.sv.set_mass(-1.0)
    with pytest.raises(ValueError, match="not a plausible bucket load"):
        r.sv.set_mass(250.0)
    row = r.sv.set_mass(mass)
    assert (row.mass_kg, row.success_level, row.success) == (mass, sl, success)
    v = r.sv.status_values(r.t)
    assert v["loaded_mass"] == f"{mass:.2f}" and v["success_level"] == str(sl) and v["success"] == str(success)


def test_mass_refused_while_an_attempt_runs(kin):
    r = Rig(kin, arm_delay=0.0).ready()
    with pytest.raises(ValueError, match="no attempt to weigh yet"):
        r.sv.set_mass(20.0)
    r.arm()
    with pytest.raises(ValueError, match="attempt 1 is running: weigh the bucket after it ends"):
        r.sv.set_mass(20.0)


def test_an_attempt_that_ended_while_armed_takes_no_mass(kin):
    """Aborted while armed: the bucket on the scale is an earlier attempt's; the mass is refused
    (its status says ran false), where an attempt aborted while running takes it (ran true)."""
    r = Rig(kin).ready()
    r.arm()
    assert r.sv.abort(r.t)[0] and r.sv.attempt.running_at is None
    with pytest.raises(ValueError, match="attempt 1 ended before it ran: nothing was loaded"):
        r.sv.set_mass(23.4)
    assert r.sv.attempt.mass is None and r.sv.status_values(r.t)["ran"] == "false"
    r = Rig(kin, arm_delay=0.0).ready()
    r.arm()
    r.step(0.3)
    assert r.sv.state == "running" and r.sv.abort(r.t)[0]
    assert r.sv.set_mass(23.4).mass_kg == 23.4 and r.sv.status_values(r.t)["ran"] == "true"


def test_the_load_cell_does_not_weigh_an_attempt_that_never_ran(kin):
    """An attempt that ended while armed (aborted: the zones moved, the operator, the e-stop) takes no
    load-cell mass, and the load cell's readings of the standing machine raise nothing: they once ended
    the supervisor node (set_mass's refusal reached its timer; a twin run, 2026-11-29). The next attempt
    that runs is weighed as usual."""
    r = Rig(kin, mass_settle_s=1.0).ready()
    r.arm()
    assert r.sv.abort(r.t)[0] and r.sv.attempt.running_at is None
    r.vel = 0.0
    for _ in range(100):                           # 2 s of readings, the machine still
        assert r.sv.load_cell(31.0, r.t) == ""
        r.step(0.02)                               # Rig.step calls update: no ValueError
    assert r.sv.attempt.mass is None and r.sv.status_values(r.t)["ran"] == "false"


def test_load_cell_median_after_the_machine_stopped(kin):
    r = Rig(kin, arm_delay=0.0, mass_settle_s=1.0).ready()
    r.arm()
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    r.vel = 0.2                                    # still moving after the end
    r.step(0.1)                                    # the end zone is judged at the control period's end
    assert r.sv.state == "success"
    for k in range(25):                            # 0.5 s of readings while moving: not used
        r.sv.load_cell(40.0, r.t)
        r.step(0.02)
    assert r.sv.attempt.mass is None
    r.vel = 0.0
    readings = [24.1, 23.8, 99.0, 24.0, 23.9]      # a spike: the median ignores it
    weighed_at = None
    for k in range(90):                            # 1.8 s still
        assert r.sv.load_cell(readings[k % 5], r.t) == ""
        r.step(0.02)
        if weighed_at is None and r.sv.attempt.mass is not None:
            weighed_at = 0.02 * (k + 1)
    # stopped once the mean speed over STOP_WINDOW_S (0.5 s) is under 0.05 rad/s (0.2 rad/s in under a quarter
    # of it: 0.36-0.38 s), then mass_settle_s (1.0 s) still
    assert weighed_at == pytest.approx(1.38, abs=0.05)
    # median of the readings of the last 1.0 s window: 10 x each of 24.1, 23.8, 99, 24.0, 23.9 -> 24.0
    assert r.sv.attempt.mass == pytest.approx(24.0) and r.sv.attempt.mass_source == "load_cell"
    assert r.sv.attempt.success_level == 3 and r.sv.attempt.success is True
    assert "dropped" in r.sv.load_cell(math.nan, r.t)
    # the operator's scale wins over the load cell, and the load cell never replaces it
    r.sv.set_mass(25.0, "operator")
    with pytest.raises(ValueError, match="weighed by the operator"):
        r.sv.set_mass(24.0, "load_cell")


def test_a_still_machine_is_weighed_through_noisy_rates_and_a_creeping_one_is_not(kin):
    """The arm's rates are differences of sampled angles (the Due's): a still machine's joint states carry rate noise
    that crosses STOP_SPEED (0.05 rad/s) in single messages: with 0.2 deg of noise on the angles, 0.05 rad/s sd over
    the firmware's 0.1 s window; with 0.1 deg, 0.12 rad/s over one 20 ms message. Judged on the mean over
    STOP_WINDOW_S (the differences telescope: the angle's change over the window), the machine is weighed in both
    (judged on each message, it needed 1 s of messages all under 0.05: at 0.1 deg in the twin it was never weighed,
    2026-11-29). An arm creeping at 0.07 rad/s under the same noise is not stopped."""
    from lhd_loading_ros.task.attempt import STOP_SPEED, STOP_WINDOW_S

    assert (STOP_SPEED, STOP_WINDOW_S) == (0.05, 0.5)
    rng = np.random.default_rng(0)
    dt = 0.02                                          # the rig's joint states, 50 Hz
    for noise_deg, n, creep, weighed in ((0.2, 5, 0.0, True), (0.1, 1, 0.0, True), (0.2, 5, 0.07, False)):
        r = Rig(kin, arm_delay=0.0, mass_settle_s=1.0).ready()
        r.arm()
        r.base_x, (r.boom, r.bucket) = END_X, LIFT
        r.step(0.1)
        assert r.sv.state == "success"
        angles = list(rng.normal(0.0, math.radians(noise_deg), n))
        crossed = 0
        for k in range(150):                           # 3 s: rates the differences of noisy angles over n messages
            angles.append(creep * dt * k + float(rng.normal(0.0, math.radians(noise_deg))))
            r.vel = (angles[-1] - angles[-1 - n]) / (n * dt)
            crossed += abs(r.vel) >= STOP_SPEED
            r.sv.load_cell(24.0, r.t)
            r.step(dt)
        assert crossed > 30, noise_deg                # single messages said "moving" again and again
        assert (r.sv.attempt.mass is not None) == weighed, (noise_deg, n, creep)
    # a boom swinging +-2 deg at 2 Hz: its mean speed over 0.5 s is 0, its positions span 4 deg: never stopped
    from lhd_loading_ros.task.attempt import STOP_SPREAD

    assert STOP_SPREAD == 0.045
    r = Rig(kin, arm_delay=0.0, mass_settle_s=1.0).ready()
    r.arm()
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    r.step(0.1)
    boom0 = r.boom
    for k in range(150):
        t = k * dt
        r.boom = boom0 + DEG(2.0) * math.sin(2 * math.pi * 2.0 * t)
        r.vel = 0.0                                    # (the rig gives every joint one velocity: the bucket's 0)
        r.sv.load_cell(24.0, r.t)
        r.step(dt)
    assert r.sv.attempt.mass is None
    r.boom = boom0 + DEG(0.5)                          # it settles: weighed once the window and mass_settle_s pass
    for _ in range(80):
        r.sv.load_cell(24.0, r.t)
        r.step(dt)
    assert r.sv.attempt.mass == pytest.approx(24.0)


def test_placement_beyond_the_trained_range_is_refused_at_arming(kin, cfg):
    """max_heading_deg / max_lateral_offset (the supervisor's -1: the parameter file's randomization.heading_max_deg
    and lateral_offset_max, the range the machine's actors were trained to start from): a machine turned or a
    bucket moved beyond them is not armed, each with its sentence; within them it is; 0 checks nothing. The tip's
    offset is where the kinematics put it: a machine turned 3.5 deg about a base_link on the axis has its lip
    TIP_AHEAD x sin(3.5 deg) = 0.104 m off, beyond 0.095, and is refused until moved back."""
    from lhd_loading_ros.task.attempt import placement_limits
    from lhd_loading_ros.task.kinematics import state_from_measurements

    lim = placement_limits(cfg, -1.0, -1.0)
    r = cfg["randomization"]
    # the lip where a training episode began: placed within 0.06 m, driven in 0.4 + 0.1 m at up to 4 deg
    assert lim == pytest.approx({"max_heading_deg": r["heading_max_deg"], "max_lateral_offset": r["lateral_offset_max"]
                                 + (r["d_attack_max"] + cfg["paper"]["episode"]["d_init"]) * math.sin(DEG(4.0))})
    assert lim == pytest.approx({"max_heading_deg": 4.0, "max_lateral_offset": 0.06 + 0.5 * 0.0697565})
    assert placement_limits(cfg, 0.0, 0.1) == {"max_heading_deg": 0.0, "max_lateral_offset": 0.1}
    for bad in ((-0.5, 0.1), (4.0, math.nan)):
        with pytest.raises(ValueError, match="expected -1"):
            placement_limits(cfg, *bad)
    with pytest.raises(ValueError, match="has no 'heading_max_deg': set both explicitly"):
        placement_limits({"paper": cfg["paper"]}, -1.0, 0.1)
    rig = Rig(kin, arm_delay=0.0, **lim).ready()
    assert rig.sv.preflight(rig.t) == []

    def tip_y():
        pos, quat, v_x = rig.sv.inputs.values["odom"]
        return state_from_measurements(kin, pos, quat, v_x, rig.sv.inputs.values["joints"], False, False).y_shovel

    rig.yaw = DEG(6.0)
    rig.base_y = 0.0
    rig.feed()
    rig.base_y = -tip_y()                       # the lip back on the axis: the heading alone is refused
    rig.feed()
    assert abs(tip_y()) < 1e-9
    probs = rig.sv.preflight(rig.t)
    assert probs == ["machine heading +6.0 deg off the pile's axis (max_heading_deg 4, the range the actors were "
                     "trained to start from): turn it straight in front of the pile"], probs
    ok, msg = rig.sv.arm(rig.t, "2025-01-01T00:00:00Z")
    assert not ok and "heading +6.0 deg" in msg
    rig.yaw, rig.base_y = DEG(-3.5), 0.0        # within 4 deg, but turned about base_link: the lip 0.104 m off
    rig.feed()
    assert tip_y() == pytest.approx(TIP_AHEAD * math.sin(DEG(-3.5)), abs=0.01)
    probs = rig.sv.preflight(rig.t)
    assert len(probs) == 1 and probs[0].startswith("bucket tip -0.10") and "max_lateral_offset 0.095 m" in probs[0]
    rig.base_y = -tip_y() + 0.09                # moved back to 9 cm off: armed
    rig.feed()
    assert rig.sv.preflight(rig.t) == []
    rig.arm()
    rig = Rig(kin, arm_delay=0.0).ready()       # the defaults: no check (the paper's protocol)
    rig.yaw = DEG(10.0)
    rig.feed()
    rig.base_y = -tip_y() + 0.1
    rig.feed()
    assert rig.sv.preflight(rig.t) == []
    for bad in (dict(max_heading_deg=-1.0), dict(max_heading_deg=math.nan), dict(max_lateral_offset=1.5)):
        with pytest.raises(ValueError, match="max_heading_deg|max_lateral_offset"):
            settings(**bad)


def test_an_imu_mounted_askew_is_refused_at_arming_and_its_zero_takes_it_off(kin):
    """max_standing_tilt_deg / imu_zero (docs/real_machine.md Calibration step 9): an IMU mounted 2 deg nose down
    reads a level machine as pitched 2 deg. Beyond 1.5 deg the machine is not armed, with a sentence saying what to
    do; with imu_zero = its reading on the level floor it is, and the final pitch and the tilt limit see the machine's
    own (level) orientation, not the mounting's."""
    from lhd_sim_node import sim_sensors as ss

    askew = ss.imu_orientation((1.0, 0.0, 0.0, 0.0), 0.0, DEG(2.0))
    r = Rig(kin, arm_delay=0.0, max_standing_tilt_deg=1.5, max_tilt_deg=8.0)
    r.imu = askew
    r.ready()
    probs = r.sv.preflight(r.t)
    assert len(probs) == 1 and probs[0].startswith("the IMU reads the standing machine tilted 2.0 deg (pitch +2.0 deg")
    assert "imu_zero_deg" in probs[0] and "Calibration step 9" in probs[0]
    ok, _ = r.sv.arm(r.t, "2025-01-01T00:00:00Z")
    assert not ok
    r = Rig(kin, arm_delay=0.0, max_standing_tilt_deg=1.5, max_tilt_deg=8.0, imu_zero=(0.0, DEG(2.0)))
    r.imu = askew
    r.ready()
    assert r.sv.preflight(r.t) == []
    tilt, pitch = r.sv._tilt(r.t)
    assert tilt == pytest.approx(0.0, abs=1e-9) and pitch == pytest.approx(0.0, abs=1e-9)
    r.arm()
    # the machine's rear lifts 9 deg: the IMU reads 11; with the zero the tilt limit (8) sees 9 and ends the attempt
    r.imu = ss.imu_orientation(ss.imu_orientation((1.0, 0.0, 0.0, 0.0), 0.0, DEG(9.0)), 0.0, DEG(2.0))
    assert r.step(0.1) == "failure"
    assert "machine tilted 9.0 deg" in r.sv.status_values(r.t)["reason"]
    with pytest.raises(ValueError, match="max_standing_tilt_deg"):
        settings(max_standing_tilt_deg=-1.0)
    with pytest.raises(ValueError, match="imu_zero"):
        settings(imu_zero=(0.0, DEG(15.0)))


def test_status_before_any_attempt(kin):
    r = Rig(kin).ready()
    r.sv.update(r.t)
    v = r.sv.status_values(r.t)
    assert v["state"] == "idle" and v["episode"] == "0" and v["loaded_mass"] == "nan"
    assert v["slope_deg"] == "20.00" and v["x_shovel"] == "0.0000" and v["z_shovel"] == "0.0150"
    assert v["reason"] == "no attempt yet: call /lhd/arm"


def test_settings_are_checked():
    with pytest.raises(ValueError, match="attempt_timeout"):
        settings(attempt_timeout=0.0)
    with pytest.raises(ValueError, match="slope range"):
        settings(slope_range_deg=(30.0, 15.0))
    with pytest.raises(ValueError, match="arm_delay"):
        settings(arm_delay=-1.0)


def test_a_new_attempt_timeout_applies_from_the_next_arming(kin):
    r = Rig(kin, arm_delay=0.0, attempt_timeout=2.0).ready()
    r.arm()
    r.sv.set_attempt_timeout(5.0)
    assert r.step(2.0) == "timeout"            # the live attempt keeps 2 s
    r.arm()
    assert r.step(4.98) == "running"
    assert r.step(0.02) == "timeout" and r.sv.attempt.reason == "attempt_timeout 5 s passed"


def test_a_teleoperated_attempt_gets_the_teleop_timeout(kin):
    """A review (2026-11-29): `lhd up real --controller teleop` cut every teleoperated attempt at the
    controllers' 10 s, where the paper's operators took 10.4-16.4 s on average (its Teleop column). A
    teleop attempt gets teleop_attempt_timeout (40 s); the label decides at arming, both ways."""
    r = Rig(kin, arm_delay=1.0, attempt_timeout=10.0).ready()
    r.sv.controller = "teleop"
    msg = r.arm()
    assert "timeout 40 s" in msg and r.sv.attempt.timeout == 40.0
    # the arm delay as for every controller (the mux holds the gamepad in it: cmd_mux.ARMED)
    assert r.sv.state == "armed" and r.step(1.0) == "running"
    assert r.step(39.98) == "running"                    # well past 10 s: the operator is still loading
    assert r.step(0.02) == "timeout" and r.sv.attempt.reason == "teleop_attempt_timeout 40 s passed"
    r.sv.set_attempt_timeout(20.0, teleop=True)
    r.sv.controller = "rld"                              # an autonomous controller: the paper's 10 s again
    r.arm()
    assert r.sv.state == "armed" and r.step(1.0) == "running"      # its arm delay
    assert r.step(10.0) == "timeout" and r.sv.attempt.reason == "attempt_timeout 10 s passed"
    r.sv.controller = "teleop"
    r.arm()
    assert r.step(1.0) == "running" and r.step(19.98) == "running" and r.step(0.02) == "timeout"
    with pytest.raises(ValueError, match="teleop_attempt_timeout"):
        settings(teleop_attempt_timeout=math.nan)


# ---------------------------------------------------------------- the machine's tilt (IMU)
def quat_zyx(yaw, pitch, roll):
    """(w, x, y, z) of Rz(yaw) Ry(pitch) Rx(roll), by the half-angle formulas."""
    cy, sy, cp, sp, cr, sr = (f(a / 2) for a in (yaw, pitch, roll) for f in (math.cos, math.sin))
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy)


def test_heading_from_the_odometry_tilt_from_the_imu():
    """with_tilt keeps the ArUco heading and takes the IMU's roll and pitch (its own heading,
    which drifts, is dropped): the result is Rz(odom yaw) Ry(pitch) Rx(roll), built by hand."""
    import numpy as np
    from lhd_loading_ros.task.kinematics import mat_to_quat, nose_down_pitch, quat_to_mat, with_tilt
    for yaw_odom, yaw_imu, pitch, roll in ((30.0, 100.0, 6.0, 2.0), (-170.0, 5.0, -3.0, -1.0), (0.0, 0.0, 9.6, 0.0)):
        q = with_tilt(quat_zyx(DEG(yaw_odom), 0.0, 0.0), quat_zyx(DEG(yaw_imu), DEG(pitch), DEG(roll)))
        expected = quat_to_mat(*quat_zyx(DEG(yaw_odom), DEG(pitch), DEG(roll)))
        assert np.allclose(quat_to_mat(*q), expected, atol=1e-12)
        assert math.degrees(nose_down_pitch(expected)) == pytest.approx(pitch, abs=1e-9)
    # every branch of Shepperd's method: near identity, and half turns about x, y and z
    for q in ((1.0, 0.0, 0.0, 0.0), (0.01, 1.0, 0.0, 0.0), (0.01, 0.0, 1.0, 0.0), (0.01, 0.0, 0.0, 1.0)):
        assert np.allclose(quat_to_mat(*mat_to_quat(quat_to_mat(*q))), quat_to_mat(*q), atol=1e-12)
    rng = np.random.default_rng(0)
    for _ in range(50):                   # mat_to_quat inverts quat_to_mat (up to the sign of q)
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        assert np.allclose(quat_to_mat(*mat_to_quat(quat_to_mat(*q))), quat_to_mat(*q), atol=1e-12)


def test_a_fresh_imu_puts_the_machine_pitch_into_the_final_pitch(kin):
    """The bucket's pitch in the world is its pitch on the machine minus the machine's nose-down
    pitch (both about y): 45.84 - 3 deg with the IMU; a stale IMU is ignored (45.84 deg)."""
    for imu_age, expected in ((0.0, math.degrees(0.8) - 3.0), (0.6, math.degrees(0.8))):
        r = Rig(kin, arm_delay=0.0).ready()
        r.arm()
        r.base_x, (r.boom, r.bucket) = END_X, LIFT
        r.feed(r.t + 0.1)
        r.sv.inputs.put("imu", quat_zyx(DEG(50.0), DEG(3.0), 0.0), r.t - imu_age)   # its own heading: ignored
        r.sv.update(r.t)
        assert r.sv.state == "success"
        assert r.sv.attempt.row().phi_final_deg == pytest.approx(expected, abs=0.005)     # the record's 0.01 deg
        # the tip's position stays the levelled pose's (what the controllers see): only the pitch changes
        x, z = tip_hand(END_X, *LIFT)
        assert (r.sv.tip.x_shovel, r.sv.tip.z_shovel) == (pytest.approx(x, abs=1e-3), pytest.approx(z, abs=1e-3))   # 3 deg about base_link: 9 cm


def test_a_tilt_beyond_max_tilt_deg_ends_the_attempt_and_the_imu_becomes_required(kin):
    r = Rig(kin, arm_delay=0.0, max_tilt_deg=8.0).ready()
    assert any("no machine orientation received (/lhd/imu" in p for p in r.sv.preflight(r.t))
    assert r.sv.arm(r.t, "x")[0] is False
    r.imu = quat_zyx(0.0, DEG(0.5), 0.0)
    r.feed()
    r.arm()
    r.imu = quat_zyx(DEG(20.0), DEG(7.9), DEG(1.0))
    assert r.step(0.2) == "running"
    r.imu = quat_zyx(0.0, DEG(9.0), 0.0)
    assert r.step(0.02) == "failure"
    row = r.sv.attempt.row()
    assert "machine tilted 9.0 deg (pitch +9.0 deg" in row.reason and "max_tilt_deg 8" in row.reason
    assert row.success is False
    # nose up (the front lifted) or on its side counts too: the tilt is the up axis from the vertical
    for yaw, pitch, roll, tilt in ((0.0, -9.0, 0.0, 9.0), (30.0, 0.0, 8.5, 8.5), (0.0, 6.0, 6.0, None)):
        r = Rig(kin, arm_delay=0.0, max_tilt_deg=8.0).ready()
        r.imu = quat_zyx(0.0, 0.0, 0.0)
        r.feed()
        r.arm()
        r.imu = quat_zyx(DEG(yaw), DEG(pitch), DEG(roll))
        r.step(0.02)
        # independently: cos(tilt) = cos(pitch) cos(roll), the up axis's vertical component
        expected = math.degrees(math.acos(math.cos(DEG(pitch)) * math.cos(DEG(roll))))
        assert r.sv.state == "failure" and f"machine tilted {expected:.1f} deg" in r.sv.attempt.reason
        assert tilt is None or expected == pytest.approx(tilt)
    # a tilted machine is not armed; in the end zone while tilted beyond the limit: a failure (safety first)
    r = Rig(kin, arm_delay=0.0, max_tilt_deg=8.0).ready()
    r.imu = quat_zyx(0.0, DEG(8.5), 0.0)
    r.feed()
    assert any("machine tilted 8.5 deg" in p for p in r.sv.preflight(r.t)) and r.sv.arm(r.t, "x")[0] is False
    r.imu = quat_zyx(0.0, 0.0, 0.0)
    r.feed()
    r.arm()
    r.base_x, (r.boom, r.bucket) = END_X, LIFT
    r.imu = quat_zyx(0.0, DEG(8.5), 0.0)
    r.feed(r.t + 0.1)
    r.sv.update(r.t)
    assert r.sv.state == "failure" and "machine tilted" in r.sv.attempt.reason
    # a silent or broken IMU is a lost input while the limit is on
    for bad, needle in ((None, "machine orientation"), ((0.0, 0.0, 0.0, 0.0), "IMU orientation is not a finite")):
        r = Rig(kin, arm_delay=0.0, max_tilt_deg=8.0).ready()
        r.imu = quat_zyx(0.0, 0.0, 0.0)
        r.feed()
        r.arm()
        if bad is None:
            r.imu = None
            r.step(0.6)
        else:
            r.imu = bad
            r.step(0.02)
        assert r.sv.state == "lost_input" and needle in r.sv.attempt.reason
    with pytest.raises(ValueError, match="max_tilt_deg"):
        settings(max_tilt_deg=-1.0)


def test_arming_refuses_a_slope_the_lidar_stopped_sending(kin):
    """A hung LiDAR node leaves the previous pile's slope and zones latched (a reviewer armed an
    attempt on a 30 deg pile with the 20 deg pile's slope and end zone, 2026-11-28): with
    slope_timeout 2 s the preflight refuses a slope not renewed for longer, naming it; a fresh one
    passes; 0 (a surveyed slope, published once) sets no limit."""
    r = Rig(kin, slope_timeout=2.0).ready()
    assert r.sv.preflight(r.t) == []
    r.step(2.5)                                            # joints, odometry, drift renewed; not the slope
    why = r.sv.preflight(r.t)
    assert len(why) == 1 and why[0].startswith("pile slope 2.5 s old (slope_timeout 2 s; /lhd/pile/slope"), why
    ok, msg = r.sv.arm(r.t, "2025-01-01T00:00:00Z")
    assert not ok and "pile slope 2.5 s old" in msg
    r.sv.inputs.put("slope", DEG(20.0), r.t)              # the next scan
    assert r.sv.preflight(r.t) == []
    none = Rig(kin).ready()
    none.step(30.0)
    assert none.sv.preflight(none.t) == [] and none.sv.s.slope_timeout == 0.0
    with pytest.raises(ValueError, match="slope_timeout = -1: expected seconds >= 0"):
        settings(slope_timeout=-1)


def test_a_slope_just_outside_the_range_is_shown_with_the_digits_that_decide(kin):
    """14.98 deg against [15, 30]: "15.0 deg is outside [15, 30]" contradicted itself."""
    r = Rig(kin).ready(slope_deg=14.98)
    (why,) = [w for w in r.sv.preflight(r.t) if "outside" in w]
    assert why.startswith("pile slope 14.980 deg is outside the controller's range [15, 30] deg"), why
    r = Rig(kin).ready(slope_deg=35.0)
    (why,) = [w for w in r.sv.preflight(r.t) if "outside" in w]
    assert why.startswith("pile slope 35.0 deg is outside"), why
