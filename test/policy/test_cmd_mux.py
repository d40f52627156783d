"""The command mux's rules (policy/cmd_mux.py), without ROS, on a hand-driven clock: selection
by priority among fresh, uncut, ungated sources; the attempt gate; the e-stop lock; zeros at once
on every transition that removes the selected source; idle zeros; cut-until-silent."""
from pathlib import Path

import pytest

from lhd_loading_ros.policy.actuator_limits import ZERO, ActuatorLimits
from lhd_loading_ros.policy.cmd_mux import CommandMux, MuxConfigError, Source, load_sources, parse_sources

ROOT = Path(__file__).resolve().parents[2]
LIMITS = ActuatorLimits((0.0, -0.191, 0.0), (2.7, 0.0, 0.2))
AUTO = [1.0, -0.191, 0.2]
TELE = [2.0, 0.0, 0.0]


@pytest.fixture
def mux():
    return CommandMux(load_sources(ROOT / "config" / "cmd_mux.yaml"), LIMITS, idle_period=0.1)


def test_shipped_sources():
    assert load_sources(ROOT / "config" / "cmd_mux.yaml") == [
        Source("teleop", "cmd/teleop", 100, 0.3, False), Source("auto", "cmd/auto", 10, 0.3, True)]


def test_auto_is_not_forwarded_without_a_running_attempt_and_idle_zeros_go_out(mux):
    assert mux.tick(0.0) == [ZERO]                            # nothing selected: a zero at once ...
    assert mux.tick(0.05) == []
    assert mux.tick(0.1) == [ZERO]                            # ... and every idle_period
    assert mux.on_command("auto", AUTO, 0.12) == []           # no /episode publisher: gated
    assert mux.on_episode("idle", 0.15) == []
    assert mux.on_command("auto", AUTO, 0.18) == []
    assert mux.states["auto"].dropped_gated == 2 and mux.active == "none"
    assert "auto: gated: attempt state is idle, not running" in mux.explain(0.19)
    assert mux.tick(0.2) == [ZERO]
    assert mux.on_episode("running", 0.21) == []
    assert mux.on_command("auto", AUTO, 0.22) == [tuple(AUTO)]
    assert mux.active == "auto" and mux.tick(0.32) == []      # selected: no idle zeros
    assert mux.on_command("auto", AUTO, 0.32) == [tuple(AUTO)]
    assert mux.on_episode("success", 0.35) == [ZERO]          # the attempt ends: a zero at once
    assert mux.active == "none"
    assert mux.on_command("auto", AUTO, 0.40) == []           # cut (and gated)
    assert mux.tick(0.45) == [ZERO]                           # idle again: 0.1 s after the zero


def test_after_an_attempt_every_source_is_cut_until_silent_for_its_timeout(mux):
    mux.on_episode("running", 0.0)
    assert mux.on_command("teleop", TELE, 0.0) == [tuple(TELE)]   # the operator drives the attempt
    assert mux.on_episode("timeout", 0.05) == [ZERO]
    t = 0.1
    while t < 1.0:                                            # deadman still held: 20 Hz, all cut
        assert mux.on_command("teleop", TELE, t) == []
        t += 0.05
    assert mux.states["teleop"].dropped_cut >= 17
    assert mux.on_command("teleop", TELE, t + 0.31) == [tuple(TELE)]  # released 0.31 s, pressed again
    # a new attempt does not uncut a controller that never fell silent
    mux.on_episode("running", 2.0)
    mux.on_command("auto", AUTO, 2.0)
    mux.on_episode("failure", 2.05)
    mux.on_episode("running", 2.1)
    assert mux.on_command("auto", AUTO, 2.1) == [] and mux.on_command("auto", AUTO, 2.2) == []
    assert mux.on_command("auto", AUTO, 2.51) == [tuple(AUTO)]    # after 0.31 s of silence


def test_teleop_overrides_auto_and_auto_resumes_after_teleop_times_out(mux):
    mux.on_episode("running", 0.0)
    assert mux.on_command("auto", AUTO, 0.0) == [tuple(AUTO)]
    assert mux.on_command("teleop", TELE, 0.05) == [tuple(TELE)]   # takes over: no zero in between
    assert mux.active == "teleop"
    assert mux.on_command("auto", AUTO, 0.1) == []            # overridden
    assert mux.on_command("teleop", ZERO, 0.1) == [ZERO]      # deadman released: teleop's own zero
    assert mux.on_command("auto", AUTO, 0.2) == []
    assert mux.tick(0.399) == []                              # teleop silent 0.299 s: still within
    assert mux.tick(0.401) == [ZERO]                          # more than its timeout: a zero at once
    assert mux.active == "auto"                               # auto is fresh (0.2): it takes over
    assert mux.on_command("auto", AUTO, 0.45) == [tuple(AUTO)]


def test_source_timeout_gives_a_zero_at_once_then_idle_zeros(mux):
    assert mux.on_command("teleop", TELE, 0.0) == [tuple(TELE)]   # not gated: no attempt needed
    assert mux.tick(0.3) == []
    assert mux.tick(0.31) == [ZERO] and mux.active == "none"
    assert mux.tick(0.35) == [] and mux.tick(0.42) == [ZERO]


def test_estop_blocks_everything_and_release_needs_silence(mux):
    mux.on_episode("running", 0.0)
    mux.on_command("teleop", TELE, 0.0)
    assert mux.on_estop(True, 0.05) == [ZERO] and mux.active == "estop"
    assert mux.on_estop(True, 0.06) == []                     # the same value again: nothing new
    for t in (0.1, 0.15, 0.2):
        assert mux.on_command("teleop", TELE, t) == [] and mux.on_command("auto", AUTO, t) == []
    assert mux.tick(0.16) == [ZERO]                           # idle zeros while locked
    assert "e-stop" in mux.explain(0.2)
    assert mux.on_estop(False, 0.25) == [] and mux.active == "none"
    assert mux.on_command("teleop", TELE, 0.3) == []          # kept talking through the e-stop: cut
    assert mux.on_command("teleop", TELE, 0.61) == [tuple(TELE)]   # after 0.31 s of silence


def test_estop_with_nothing_selected_still_sends_a_zero_at_once(mux):
    assert mux.on_estop(True, 0.0) == [ZERO]


def test_bad_commands_are_rejected_and_out_of_range_ones_clamped(mux):
    mux.on_episode("running", 0.0)
    assert mux.on_command("auto", [5.0, 0.5, -1.0], 0.0) == [(2.7, 0.0, 0.0)]
    assert mux.states["auto"].clamped == 1
    assert mux.on_command("auto", [float("nan"), 0.0, 0.0], 0.05) == [ZERO]   # from the selected source
    assert mux.states["auto"].rejected == 1 and "non-finite wheels" in mux.states["auto"].last_rejection
    assert mux.on_command("teleop", [1.0, 0.0], 0.1) == []    # not selected: counted only
    assert mux.states["teleop"].rejected == 1 and "has 2 values" in mux.states["teleop"].last_rejection
    assert mux.states["teleop"].last_arrival is None          # a rejected message is no sign of life
    assert mux.on_command("auto", AUTO, 0.1) == [tuple(AUTO)]


@pytest.mark.parametrize("doc, match", [
    ({"sources": []}, "non-empty list"),
    ({"sources": [{"name": "a", "topic": "x", "priority": 1, "timeout": 0.3}]}, "expected exactly the keys"),
    ({"sources": [{"name": "none", "topic": "x", "priority": 1, "timeout": 0.3, "gated": True}]}, "other than"),
    ({"sources": [{"name": "a", "topic": "x", "priority": 300, "timeout": 0.3, "gated": True}]}, "0..255"),
    ({"sources": [{"name": "a", "topic": "x", "priority": 1, "timeout": 0, "gated": True}]}, r"\(0, 10\]"),
    ({"sources": [{"name": "a", "topic": "x", "priority": 1, "timeout": 0.3, "gated": "yes"}]}, "gated = 'yes'"),
    ({"sources": [{"name": "a", "topic": "x", "priority": 1, "timeout": 0.3, "gated": True},
                  {"name": "b", "topic": "y", "priority": 1, "timeout": 0.3, "gated": True}]}, "share a priority"),
    ({"sources": [], "locks": []}, "non-empty list"),
    ({"sources": [{"name": "a", "topic": "x", "priority": 1, "timeout": 0.3, "gated": True}], "locks": []},
     r"unknown keys \['locks'\]"),
])
def test_bad_mux_configs_are_refused(doc, match):
    with pytest.raises(MuxConfigError, match=match):
        parse_sources(doc, "mux.yaml")


def _drive(mux, t0, t1, status_every=None, auto=True):
    """Ticks every 10 ms and auto commands every 100 ms from t0 to t1 (and a running status every
    status_every s); returns what left the mux, with times."""
    out = []
    k = 0
    while True:
        t = round(t0 + 0.01 * k, 6)
        if t > t1:
            return out
        if status_every and k % round(status_every / 0.01) == 0:
            out += [(t, c) for c in mux.on_episode("running", t)]
        if auto and k % 10 == 0:
            out += [(t, c) for c in mux.on_command("auto", AUTO, t)]
        out += [(t, c) for c in mux.tick(t)]
        k += 1


def test_a_running_attempt_whose_status_stops_arriving_ends(mux):
    """The supervisor publishes its status at 2 Hz; killed or hung (its DDS lease outlives it by
    about 20 s, so the graph still shows it), its last status says running for ever. After
    status_timeout (1.5 s) without one the attempt has ended: a zero at once, auto and teleop cut
    as after any end. Times by hand: the last status at 1.0 s, ticks every 10 ms: the first tick
    with an age over 1.5 s is at 2.51 s."""
    assert mux.status_timeout == 1.5
    out = _drive(mux, 0.0, 1.0, status_every=0.5)
    assert all(c == tuple(AUTO) for _, c in out if _ > 0.0) and mux.active == "auto"
    out = _drive(mux, 1.01, 3.0)                                   # auto keeps commanding, no status
    zeros = [t for t, c in out if c == ZERO]
    assert zeros and zeros[0] == pytest.approx(2.51)
    i = next(i for i, (t, c) in enumerate(out) if c == ZERO)
    assert all(c == tuple(AUTO) for _, c in out[:i])               # (the one at 2.51 s came before the tick)
    assert all(c == ZERO for _, c in out[i:]) and len(out[i:]) >= 4   # then only the idle zeros
    assert mux.active == "none" and mux.episode_state == "status lost"
    assert "the running attempt's status stopped arriving (1.5 s without one" in mux.explain(3.0)
    assert mux.states["auto"].cut
    assert mux.on_command("teleop", TELE, 3.0) == [tuple(TELE)]    # teleop was silent: the operator drives
    # the next attempt runs normally once its status arrives
    assert mux.on_episode("idle", 3.1) == [] and mux.on_episode("running", 3.2) == []


def test_an_attempt_whose_status_was_lost_does_not_run_again_when_it_comes_back(mux):
    """A supervisor that hung for 2 s wakes up and says attempt 4 is running: the mux declared it
    lost and keeps it ended (the policy node does the same); attempt 5 runs."""
    mux.on_episode("running", 0.0, "4")
    _drive(mux, 0.0, 2.0)                                  # no status after 0.0: lost at 1.51 s
    assert mux.episode_state == "status lost" and mux.lost_keys == {"4"}
    assert mux.on_episode("running", 2.1, "4") == [] and mux.episode_state == "status lost"
    out = _drive(mux, 2.11, 3.0, status_every=None)
    assert not any(c == tuple(AUTO) for _, c in out)      # auto cut and gated: nothing forwarded
    mux.on_episode("idle", 3.0, "4")
    mux.on_episode("running", 3.1, "5")
    assert mux.running
    assert mux.on_command("auto", AUTO, 3.6) == [tuple(AUTO)]   # after 0.3 s of silence: uncut


def test_every_lost_attempt_stays_ended_and_one_without_a_key_until_its_publisher_moves_on(mux):
    """A third-party supervisor's status may carry no `episode` key (docs/ros_nodes.md). Such an attempt
    lost and its `running` coming back (the same publisher waking up) must not drive again: only after the
    publisher says anything else (ended, idle) is its next `running` a new attempt. Keyed attempts: every
    lost one stays ended, not only the latest (a review, 2026-11-29, twelfth session: the key-less case
    drove 29 commands after the outage)."""
    mux.on_episode("running", 0.0)                        # no key
    _drive(mux, 0.0, 2.0)
    assert mux.episode_state == "status lost" and mux.lost_unkeyed
    mux.on_episode("running", 2.1)                        # the same attempt's status back
    out = _drive(mux, 2.11, 3.0)
    assert mux.episode_state == "status lost" and not any(c == tuple(AUTO) for _, c in out)
    mux.on_episode("idle", 3.0)                           # the publisher moved on ...
    assert not mux.lost_unkeyed
    mux.on_episode("running", 3.1)                        # ... its next running is a new attempt
    assert mux.running and mux.on_command("auto", AUTO, 3.6) == [tuple(AUTO)]
    # two keyed attempts lost in turn: the first one's late status does not run either
    for key, t in (("7", 10.0), ("8", 20.0)):
        mux.on_episode("running", t, key)
        _drive(mux, t, t + 2.0)
        assert mux.episode_state == "status lost"
    assert mux.lost_keys == {"7", "8"}
    mux.on_episode("running", 22.5, "7")
    assert not mux.running


def test_the_mux_s_own_pause_is_not_a_lost_status(mux):
    """The mux's process stalls for 2 s (ticks stop). The statuses sent meanwhile do not wait in
    its queue (the reliable transport repairs them at its next heartbeat), so the next one comes
    with the supervisor's next 2 Hz publication, 0.45 s after the mux wakes: the status' age counts
    from the end of the pause, and the attempt runs on. With the rule off (status_timeout 0), 3 s
    of silence end nothing."""
    _drive(mux, 0.0, 1.0, status_every=0.5)
    assert mux.tick(3.0) == [ZERO]                        # auto's own 0.3 s timeout: a zero, not an end
    assert mux.episode_state == "running" and mux.resumed_at == 3.0
    out = _drive(mux, 3.01, 3.44)                         # ticks and auto commands, no status yet
    assert mux.episode_state == "running"
    out += _drive(mux, 3.45, 5.0, status_every=0.5)
    assert mux.episode_state == "running" and mux.active == "auto"
    assert [c for t, c in out if t >= 3.1] and all(c == tuple(AUTO) for t, c in out if t >= 3.1)
    # but a supervisor that stops during the mux's pause is found 1.5 s of running time after it
    m2 = CommandMux(load_sources(ROOT / "config" / "cmd_mux.yaml"), LIMITS, idle_period=0.1)
    _drive(m2, 0.0, 1.0, status_every=0.5)
    m2.tick(3.0)
    out = _drive(m2, 3.01, 5.0)
    assert next(t for t, c in out if c == ZERO) == pytest.approx(4.51) and m2.episode_state == "status lost"
    off = CommandMux(load_sources(ROOT / "config" / "cmd_mux.yaml"), LIMITS, idle_period=0.1, status_timeout=0.0)
    _drive(off, 0.0, 0.1, status_every=0.5)
    out = _drive(off, 0.11, 4.0)
    assert off.episode_state == "running" and all(c == tuple(AUTO) for t, c in out if t > 0.2)


def test_an_armed_attempt_holds_every_source_the_gamepad_too(mux):
    """A field review (2026-11-29): the ungated gamepad drove through the supervisor's 1 s arm delay, so a
    teleop attempt's first second was neither timed nor sampled for drift. While an attempt is armed no source
    is forwarded; the gamepad driving when the arming came is stopped at once, and drives again at running."""
    mux.on_episode("idle", 0.0)
    assert mux.on_command("teleop", TELE, 0.05) == [tuple(TELE)]     # placing the machine before an attempt
    assert mux.on_episode("armed", 0.1) == [ZERO]                     # armed: stopped at once
    assert mux.active == "none"
    assert mux.on_command("teleop", TELE, 0.15) == [] and mux.on_command("teleop", TELE, 0.2) == []
    assert mux.states["teleop"].dropped_gated == 2
    assert "teleop: held: an attempt is armed; every source waits for it to run" in mux.explain(0.21)
    assert mux.on_episode("running", 1.1) == []
    assert mux.on_command("teleop", TELE, 1.15) == [tuple(TELE)]     # the attempt runs: the operator drives it
