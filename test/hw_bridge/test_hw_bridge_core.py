"""Bridge logic without ROS: command safety, dead band, watchdog, drift."""
import math

import pytest

from lhd_hw_bridge.bridge_core import (DRIFT_ODOM_MAX_AGE, BridgeParams, CommandMapper, CommandRejected,
                                       CommandScheduler, DeviceClock, DriftWindow, Watchdog, WheelAngles, detect_drift,
                                       joint_state_arrays)
from lhd_hw_bridge.protocol import CommandFrame, SensorFrame


@pytest.fixture
def bp(cfg):
    return BridgeParams.from_config(cfg)


def test_full_speed_commands_open_the_valves(bp):
    m = CommandMapper(bp)
    assert m.map([2.0, -0.191, 0.2]) == CommandFrame(2.0, 1, 1, True)
    assert m.map([0.0, 0.0, 0.0]) == CommandFrame(0.0, 0, 0, True)
    # dead band: half of full speed
    assert m.map([1.0, -0.0956, 0.1]).valve_boom == 1 and m.map([1.0, -0.0956, 0.1]).valve_bucket == 1
    assert m.map([1.0, -0.0954, 0.0999]) == CommandFrame(1.0, 0, 0, True)
    assert m.clamped == 0 and m.rejected == 0


def test_unsafe_requests_are_clamped_whatever_the_command_says(bp):
    m = CommandMapper(bp)
    f = m.map([-1.0, 0.191, -0.2])        # reverse wheels, lower boom, tilt bucket forward
    assert f == CommandFrame(0.0, 0, 0, True)
    assert m.map([9.0, 0.0, 0.0]).wheel_setpoint == 2.7
    assert m.clamped == 2


@pytest.mark.parametrize("bad, why", [([1.0, 2.0], "3 values"), ([1.0, 2.0, 3.0, 4.0], "3 values"),
                                      ([math.nan, 0.0, 0.0], "non-finite"), ([0.0, math.inf, 0.0], "non-finite")])
def test_malformed_commands_are_rejected_and_counted(bp, bad, why):
    m = CommandMapper(bp)
    with pytest.raises(CommandRejected, match=why):
        m.map(bad)
    assert m.rejected == 1


def test_watchdog_times_out_and_rearms(bp):
    w = Watchdog(0.3)
    assert w.stale(0.0)                    # nothing received yet
    w.feed(1.0)
    assert not w.stale(1.29) and w.stale(1.3) and w.trips == 1
    w.feed(2.0)
    w.rearm(2.1)                           # reconnection: the command from before it is void
    assert w.stale(2.15)
    w.feed(2.2)
    assert not w.stale(2.25)


def test_drift_from_the_window_and_from_current_only_without_it(bp):
    f = SensorFrame(0, 0, 0, 0, 0, 2.7, 2.7, 2.7, 3.0, 3.0, 5.0, 0, 0, 0)
    hot = SensorFrame(0, 0, 0, 0, 0, 2.7, 2.7, 2.7, 9.0, 3.0, 13.0, 0, 0, 0)
    assert detect_drift(f, None, bp) == (False, False)            # travel unknown, currents under the presets
    assert detect_drift(hot, None, bp) == (True, True)            # travel unknown: the currents decide
    assert detect_drift(hot, (False, False), bp) == (False, False)  # travel known: a motor at its limit is not drift
    assert detect_drift(f, (True, False), bp) == (True, False)


def _feed(w, wheel_rim, machine_v, t_end, latency, r, frame_dt=0.02, odom_dt=1 / 30):
    """Wheel frames every frame_dt with the angles rim(t) / r; odometry every odom_dt with the speed
    machine_v(t), stamped with its image's instant and handed over `latency` later (only those arrived
    by t_end)."""
    t = 0.0
    while t <= t_end + 1e-9:
        a = wheel_rim(t) / r
        w.add_wheels(t, (a, a, a), 0)
        t += frame_dt
    t = 0.0
    while t + latency <= t_end + 1e-9:
        w.add_odom(t, machine_v(t))
        t += odom_dt


def test_drift_window_is_the_simulators_rule_over_one_period(bp):
    """The simulator's rule (LhdSimulator.wheel_drift) by hand: over T = 0.1 s a wheel drifts when
    |rim travel - machine travel| > max(0.05 m/s x T, 0.3 x the larger)."""
    r, T = bp.wheel_radius, bp.control_period
    assert T == pytest.approx(0.1) and bp.drift_slip_ratio == 0.3 and bp.drift_min_speed == 0.05
    for rim_speed, machine_speed, expected in [(0.30, 0.30, False), (0.30, 0.22, False), (0.30, 0.20, True),
                                               (0.04, 0.0, False), (0.06, 0.0, True), (0.0, 0.0, False)]:
        # (0.30 vs 0.22: 0.08 < 0.3 x 0.30 = 0.09; vs 0.20: 0.10 > 0.09; at rest the 0.05 m/s floor)
        w = DriftWindow(T)
        _feed(w, lambda t: rim_speed * t, lambda t: machine_speed, 1.0, 0.0, r)
        dx, dth = w.travels()
        assert dx == pytest.approx(machine_speed * T, abs=1e-9)
        assert dth[0] * r == pytest.approx(rim_speed * T, abs=1e-9)
        assert w.slips(bp) == (expected, expected), (rim_speed, machine_speed)


def test_drift_window_aligns_the_late_camera_with_the_wheels(bp):
    """A machine that accelerates from rest at 2 m/s^2 with its wheels rolling (no slip at all), seen by
    a camera whose odometry arrives 80 ms after its image. The newest wheel speed (0.40 m/s at 0.2 s)
    against the newest camera speed (0.24 m/s, from 0.12 s) differ by 0.16 > 0.3 x 0.40: the comparison
    the bridge made before 2026-11-29 called it drift. The window, at the image's instant, does not: its
    travel, the speed's integral over 0.02-0.12 s, is a (0.12^2 - 0.02^2) / 2 = 14.0 mm, by hand."""
    r = bp.wheel_radius
    a = 2.0
    w = DriftWindow(bp.control_period)
    _feed(w, lambda t: 0.5 * a * t * t, lambda t: a * t, 0.2, 0.08, r, odom_dt=0.02)
    rim_now, v_cam = a * 0.2, a * 0.12
    assert abs(rim_now - v_cam) > max(bp.drift_min_speed, bp.drift_slip_ratio * rim_now)   # the old rule
    dx, dth = w.travels()
    assert dx == pytest.approx(0.5 * a * (0.12 ** 2 - 0.02 ** 2), abs=1e-9)
    assert dth[0] * r == pytest.approx(dx, abs=1e-9)
    assert w.slips(bp) == (False, False)
    # the same, the front wheels spinning 60 % faster than they roll: drift, rear still rolling
    w = DriftWindow(bp.control_period)
    t = 0.0
    while t <= 0.5 + 1e-9:
        x = 0.5 * a * t * t / r
        w.add_wheels(t, (1.6 * x, 1.6 * x, x), 0)
        t += 0.02
    t = 0.0
    while t + 0.08 <= 0.5 + 1e-9:
        w.add_odom(t, a * t)
        t += 1 / 30
    assert w.slips(bp) == (True, False)


def test_drift_window_has_no_answer_on_stale_odometry_or_a_gap(bp):
    r, T = bp.wheel_radius, bp.control_period
    # not yet a period of odometry inside the wheel frames
    w = DriftWindow(T)
    assert w.travels() is None and w.reason == "no odometry yet"
    _feed(w, lambda t: 0.3 * t, lambda t: 0.3, 0.08, 0.0, r)
    assert w.travels() is None and w.slips(bp) is None and "do not cover" in w.reason
    # odometry stops (the marker lost) while the wheels spin up: the last window is not reused past
    # DRIFT_ODOM_MAX_AGE; with no answer the motor currents decide
    w = DriftWindow(T)
    _feed(w, lambda t: 0.3 * t, lambda t: 0.3, 1.0, 0.0, r)
    assert w.slips(bp) == (False, False)
    t_last = w.newest[0]
    for k in range(1, 30):
        t = 1.0 + 0.02 * k
        w.add_wheels(t, ((0.3 + 1.5 * (t - 1.0)) * t / r,) * 3, 0)
        if t - t_last <= DRIFT_ODOM_MAX_AGE:
            assert w.travels() is not None
        else:
            assert w.slips(bp) is None and "older than the newest wheel frame" in w.reason
    # a restart of the wheels' integration (a link gap) inside the window: no answer until a period after it
    w = DriftWindow(T)
    for k in range(30):
        t = 0.02 * k
        w.add_wheels(t, (0.3 * t / r,) * 3, 0 if t < 0.5 else 1)
        w.add_odom(t, 0.3)
    assert w.travels() is None and "gap" in w.reason
    for k in range(30, 40):
        t = 0.02 * k
        w.add_wheels(t, (0.3 * t / r,) * 3, 1)
        w.add_odom(t, 0.3)
    assert w.slips(bp) == (False, False)
    # a non-finite speed and a repeated stamp are not kept; a stamp or a frame time that goes back
    # (a restarted camera, a clock stepped back) starts that history over
    assert not w.add_odom(0.9, float("nan")) and not w.add_odom(0.78, 0.3)
    assert w.slips(bp) == (False, False)
    assert w.add_odom(0.5, 0.3) and w.travels() is None
    w.add_wheels(0.1, (0.0, 0.0, 0.0), 1)
    assert w.newest == (0.5, 0.1)
    with pytest.raises(ValueError, match="control period"):
        DriftWindow(0.0)


def test_device_clock_stamps_frames_when_they_were_measured():
    """Frames measured every 20 ms by the device, arriving in bursts and late (2-40 ms, never less than
    2 ms): each stamp is the device's instant plus the smallest delay seen, so it is the measurement
    instant plus 2 ms, whatever its own arrival delay; the uint32 clock's wrap is unwrapped, and a
    device reset starts over."""
    import random

    rng = random.Random(3)
    dc = DeviceClock()
    t0 = 1000.0
    start_us = (1 << 32) - 1_000_000              # the device clock wraps 1 s into the run
    for k in range(300):
        t_meas = t0 + 0.02 * k
        delay = 0.002 if k % 25 == 0 else 0.002 + rng.uniform(0.0, 0.038)
        st = dc.stamp((start_us + 20_000 * k) % (1 << 32), t_meas + delay)
        if k >= 25:                                # once a frame has come through with the least delay
            assert st == pytest.approx(t_meas + 0.002, abs=1e-9), k
    dc.stamp(5, 2000.0)                            # a reset: the device clock went back
    assert dc.stamp(20_005, 2000.03) == pytest.approx(2000.02)


def test_wheel_angles_count_their_restarts():
    wa = WheelAngles()
    mk = lambda us: SensorFrame(us, 0, 0, 0, 0, 1.0, 1.0, 1.0, 0, 0, 0, 0, 0, 0)   # noqa: E731
    wa.update(mk(0))
    assert wa.restarts == 1
    wa.update(mk(20_000))
    assert wa.restarts == 1 and wa.angles[0] == pytest.approx(0.02)
    wa.update(mk(1_000_000))                      # a 0.98 s gap: not integrated, a new segment
    assert wa.restarts == 2 and wa.angles[0] == pytest.approx(0.02)


def test_joint_state_contents():
    f = SensorFrame(0, -0.2, 0.3, -0.19, 0.2, 1.0, 1.1, 1.2, 0, 0, 0, 1, 1, 1)
    pos, vel = joint_state_arrays(f)
    assert pos == [-0.2, 0.3, 0.0, 0.0, 0.0, 0.0]
    assert vel == [-0.19, 0.2, 1.0, 1.1, 1.2, 1.2]
    # the arm's zeros (the angles the device reports in the attack pose) come off the positions, not the rates
    pos, vel = joint_state_arrays(f, zeros=(0.035, -0.02))
    assert pos[:2] == pytest.approx([-0.235, 0.32]) and vel[:2] == [-0.19, 0.2]


def test_arm_zero_limits():
    from lhd_hw_bridge.bridge_core import arm_zero_problem

    assert arm_zero_problem(0.0) is None and arm_zero_problem(-0.35) is None and arm_zero_problem(0.1) is None
    assert "in rad, not deg" in arm_zero_problem(2.0)          # 2 deg typed as rad
    assert "expected the angle in rad" in arm_zero_problem(float("nan"))
    assert "expected the angle in rad" in arm_zero_problem(True)


def test_wheel_angles_are_the_reported_speeds_integrated_on_the_device_clock():
    """By hand: 100 frames 10 ms apart at 2.0 / 1.0 / 0.5 rad/s are 0.99 s of travel: 1.98, 0.99,
    0.495 rad (the first frame only starts the clock); a speed ramp integrates as a trapezoid; the
    uint32 microsecond clock wrapping is 10 ms like any other; a gap of 2 s (a lost link) or the
    clock going back adds nothing; never a NaN."""
    from lhd_hw_bridge.bridge_core import DEVICE_CLOCK_WRAP_US, WheelAngles

    def frame(t_us, fl, fr, rear):
        return SensorFrame(t_us % DEVICE_CLOCK_WRAP_US, 0, 0, 0, 0, fl, fr, rear, 0, 0, 0, 1, 0, 0)

    w = WheelAngles()
    for k in range(100):
        pos, _ = joint_state_arrays(frame(5_000_000 + 10_000 * k, 2.0, 1.0, 0.5), w)
    assert pos[2:] == pytest.approx([1.98, 0.99, 0.495, 0.495], abs=1e-12)
    w = WheelAngles()
    w.update(frame(0, 0.0, 0.0, 0.0))
    assert w.update(frame(100_000, 1.0, 1.0, 1.0)) == pytest.approx([0.05] * 4)      # (0 + 1) / 2 x 0.1 s
    w = WheelAngles()
    w.update(frame(DEVICE_CLOCK_WRAP_US - 5_000, 1.0, 1.0, 1.0))
    assert w.update(frame(DEVICE_CLOCK_WRAP_US + 5_000, 1.0, 1.0, 1.0)) == pytest.approx([0.01] * 4)
    before = w.update(frame(DEVICE_CLOCK_WRAP_US + 2_005_000, 1.0, 1.0, 1.0))      # 2 s later
    assert before == pytest.approx([0.01] * 4)
    assert w.update(frame(DEVICE_CLOCK_WRAP_US + 1_000_000, 1.0, 1.0, 1.0)) == pytest.approx([0.01] * 4)
    assert all(math.isfinite(a) for a in w.angles)


def test_a_zero_dead_band_would_open_the_valves_for_a_zero_command_and_is_refused(bp):
    import dataclasses

    from lhd_hw_bridge.bridge_core import deadband_problem

    # why the rule exists: the mapping itself opens both valves for u = 0 at a dead band of 0
    assert CommandMapper(dataclasses.replace(bp, valve_deadband=0.0)).map([0.0, 0.0, 0.0]) == CommandFrame(0.0, 1, 1, True)
    assert CommandMapper(dataclasses.replace(bp, valve_deadband=1e-6)).map([0.0, 0.0, 0.0]) == CommandFrame(0.0, 0, 0, True)
    assert "zero command would open the valves" in deadband_problem(0.0)
    assert deadband_problem(-0.1) and deadband_problem(1e-6) is None and deadband_problem(0.5) is None


def test_command_rate_rule_leaves_room_for_a_lost_frame():
    from lhd_hw_bridge.bridge_core import command_rate_problem, min_command_rate

    # 250 ms device watchdog: two periods (one frame lost) within 125 ms -> period <= 62.5 ms -> 16 Hz
    assert min_command_rate(0.25) == pytest.approx(16.0)
    assert command_rate_problem(16.0, 0.25) is None and command_rate_problem(50.0, 0.25) is None
    assert "expected >= 16 Hz" in command_rate_problem(15.9, 0.25)


def test_rearming_is_not_a_watchdog_trip():
    w = Watchdog(0.3)
    w.feed(1.0)
    assert not w.stale(1.1)
    w.rearm(1.2)                           # reconnection or e-stop release while commands flow
    assert w.stale(1.21) and w.trips == 0
    # what the supervisor is told (hw/status command_stale): only commands that stopped coming, not
    # the wait for a first command after a reconnection (a review: a reconnection mid-attempt ended
    # it with a reason blaming the mux); asking it changes nothing
    assert not w.timed_out(1.21) and w.trips == 0
    assert w.timed_out(1.3) and w.timed_out(1.5) and w.trips == 0
    assert not Watchdog(0.3).timed_out(5.0)      # no command yet: the start, not a stop


def test_command_frames_leave_at_the_rate_and_a_changed_command_at_once():
    """The bridge's 5 ms tick over 2 s, a 50 Hz command rate, a policy changing its command at
    10 Hz at instants off the tick and a teleop burst changing it every 1 ms: a changed command
    leaves at the first tick after it (within 5 ms: the tick) instead of up to 20 ms later; frames
    are never closer than the 2 ms gap and never further apart than one period plus a tick."""
    sch = CommandScheduler(period=0.02, min_gap=0.002, now=0.0)
    cmd, sent, changed_at, delays = CommandFrame(0.0, 0, 0, True), [], None, []
    for k in range(400):
        now = k * 0.005
        arrivals = [now - 0.005 + 0.0037] if k % 20 == 7 else []          # 10 Hz, 3.7 ms into a tick
        if 300 <= k < 310:
            arrivals = [now - 0.005 + 0.001 * j for j in range(5)]         # a 1 kHz burst
        for t in arrivals:
            cmd = CommandFrame(round(0.1 * (k % 27) + 0.01 * t, 3), 0, 0, True)   # every arrival a new set-point
            changed_at = changed_at if changed_at is not None else t
        if sch.due(now, cmd):
            sch.sent(now, cmd)
            sent.append(now)
            if changed_at is not None and cmd == sch.last_sent:
                delays.append(now - changed_at)
                changed_at = None
    gaps = [b - a for a, b in zip(sent, sent[1:])]
    assert min(gaps) >= 0.002
    assert max(gaps) <= 0.02 + 0.005 + 1e-9
    assert max(delays) <= 0.005 + 1e-9            # (the old fixed cadence: up to 20 ms)
    assert 100 <= len(sent) <= 100 + 20 + 10        # the rate, plus at most one early frame per change
    # an unchanged command keeps the plain 50 Hz cadence
    sch = CommandScheduler(period=0.02, min_gap=0.002, now=0.0)
    steady = [k * 0.005 for k in range(400) if sch.due(k * 0.005, cmd) and sch.sent(k * 0.005, cmd) is None]
    gaps = [b - a for a, b in zip(steady, steady[1:])]
    assert 99 <= len(steady) <= 100 and all(0.015 - 1e-9 <= g <= 0.025 + 1e-9 for g in gaps)   # within a tick
