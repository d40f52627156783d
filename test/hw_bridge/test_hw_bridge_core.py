"""Bridge logic without ROS: command safety, dead band, watchdog, drift."""
import math

import pytest

from lhd_hw_bridge.bridge_core import (BridgeParams, CommandMapper, CommandRejected, CommandScheduler, Watchdog,
                                       detect_drift, joint_state_arrays)
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


def test_drift_from_speed_mismatch_and_from_current(bp):
    f = SensorFrame(0, 0, 0, 0, 0, 2.7, 2.7, 2.7, 3.0, 3.0, 5.0, 0, 0, 0)
    assert detect_drift(f, 0.37, bp) == (False, False)        # rim 0.37 m/s, machine 0.37 m/s
    assert detect_drift(f, 0.02, bp) == (True, True)          # spinning in place
    assert detect_drift(f, None, bp) == (False, False)        # speed unknown: currents only
    hot = SensorFrame(0, 0, 0, 0, 0, 2.7, 2.7, 2.7, 9.0, 3.0, 13.0, 0, 0, 0)
    assert detect_drift(hot, None, bp) == (True, True)


def test_joint_state_contents():
    f = SensorFrame(0, -0.2, 0.3, -0.19, 0.2, 1.0, 1.1, 1.2, 0, 0, 0, 1, 1, 1)
    pos, vel = joint_state_arrays(f)
    assert pos == [-0.2, 0.3, 0.0, 0.0, 0.0, 0.0]
    assert vel == [-0.19, 0.2, 1.0, 1.1, 1.2, 1.2]


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
