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
