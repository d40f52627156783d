"""Gamepad mapping and the teleop state machine (policy/joy_mapping.py), without ROS.

Expected rad/s are worked out by hand from the task ranges of config/lhd_params.yaml
(wheels [0, 2.7], boom [-0.191, 0] (negative lifts), bucket [0, 0.2]) and the shipped files:
  trigger press p = (v - rest) / (pressed - rest); deadzone d: (p - d) / (1 - d) beyond d;
  stick: (|v| - d) / (1 - d) with the sign of v (negated first if invert);
  fraction s > 0 -> s * hi, s < 0 -> s * |lo|.
"""
import math
import re
from pathlib import Path

import pytest

from lhd_loading_ros.policy.actuator_limits import ZERO, ActuatorLimits, CommandInvalid
from lhd_loading_ros.policy.joy_mapping import (SHIPPED, MappingError, TeleopCore, deadzone, load_mapping,
                                                parse_mapping, to_rad_s)

ROOT = Path(__file__).resolve().parents[2]
TELEOP = ROOT / "config" / "teleop"


@pytest.fixture(scope="module")
def limits(params):
    return ActuatorLimits.from_params(params)


def test_task_ranges_are_the_ones_the_hand_values_assume(limits):
    assert limits.lo == (0.0, -0.191, 0.0) and limits.hi == (2.7, 0.0, 0.2)


# ------------------------------------------------------------------ the joy driver's messages
def xbox_msg(lx=0.0, ly=0.0, lt=1.0, rx=0.0, ry=0.0, rt=1.0, pressed=()):
    """joy_node / joy_linux with an Xbox pad (xpad): 8 axes, 11 buttons, triggers +1 released."""
    buttons = [0] * 11
    for b in pressed:
        buttons[b] = 1
    return [lx, ly, lt, rx, ry, rt, 0.0, 0.0], buttons


def ds4_msg(rx=0.0, ry=0.0, r2=1.0, pressed=()):
    """joy_node with a DualShock 4 (hid-sony): 8 axes, 13 buttons."""
    buttons = [0] * 13
    for b in pressed:
        buttons[b] = 1
    return [0.0, 0.0, 1.0, rx, ry, r2, 0.0, 0.0], buttons


def gc_msg(rightx=0.0, righty=0.0, rtrigger=0.0, pressed=()):
    """game_controller_node: 6 axes, 21 buttons, triggers 0 released, -1 fully pressed."""
    buttons = [0] * 21
    for b in pressed:
        buttons[b] = 1
    return [0.0, 0.0, rightx, righty, 0.0, rtrigger], buttons


HALF_TRIGGER = 0.45 / 0.95 * 2.7            # p = 0.5, deadzone 0.05: (0.5 - 0.05) / 0.95 of 2.7 rad/s


# (file, message, expected [u_wheels, u_boom, u_bucket]) worked out by hand
CASES = {
    "xbox": [
        (xbox_msg(), (0.0, 0.0, 0.0)),                                   # everything at rest
        (xbox_msg(rt=-1.0), (2.7, 0.0, 0.0)),                            # RT fully pressed: p = 1
        (xbox_msg(rt=0.0), (HALF_TRIGGER, 0.0, 0.0)),                    # RT half: 1.27894736842 rad/s
        (xbox_msg(rt=0.95), (0.0, 0.0, 0.0)),                            # p = 0.025 inside the deadzone
        (xbox_msg(pressed=(3,)), (0.0, -0.191, 0.0)),                    # Y lifts at full speed
        (xbox_msg(pressed=(0,)), (0.0, 0.0, 0.2)),                       # A curls back at full speed
        (xbox_msg(ry=0.75), (0.0, -0.0955, 0.0)),                        # stick up 0.75: -(0.25/0.5) * 0.191
        (xbox_msg(ry=-1.0), (0.0, 0.0, 0.0)),                            # stick down asks to lower: refused
        (xbox_msg(ry=0.4), (0.0, 0.0, 0.0)),                             # inside the 0.5 deadzone
        (xbox_msg(rx=1.0), (0.0, 0.0, 0.2)),                             # stick left curls back
        (xbox_msg(rx=-1.0), (0.0, 0.0, 0.0)),                            # stick right would tip forward
        (xbox_msg(ry=1.0, pressed=(3,)), (0.0, -0.191, 0.0)),            # Y + stick: -2 clamped to -1
        (xbox_msg(lt=-1.0, ly=1.0, lx=1.0), (0.0, 0.0, 0.0)),           # LT and left stick do nothing
        (xbox_msg(rt=-1.0, pressed=(3, 0)), (2.7, -0.191, 0.2)),
    ],
    "f710": [                                                           # X mode: the Xbox layout
        (xbox_msg(rt=-1.0), (2.7, 0.0, 0.0)),
        (xbox_msg(rt=0.0, pressed=(3,)), (HALF_TRIGGER, -0.191, 0.0)),
        (xbox_msg(rx=0.75), (0.0, 0.0, 0.1)),                            # (0.25/0.5) * 0.2
    ],
    "ps4": [
        (ds4_msg(), (0.0, 0.0, 0.0)),
        (ds4_msg(r2=-1.0), (2.7, 0.0, 0.0)),                             # R2 fully pressed
        (ds4_msg(r2=0.0), (HALF_TRIGGER, 0.0, 0.0)),
        (ds4_msg(pressed=(2,)), (0.0, -0.191, 0.0)),                     # TRIANGLE lifts
        (ds4_msg(pressed=(0,)), (0.0, 0.0, 0.2)),                        # CROSS curls
        (ds4_msg(pressed=(3,)), (0.0, 0.0, 0.0)),                        # SQUARE: nothing
        (ds4_msg(ry=1.0), (0.0, -0.191, 0.0)),                           # right stick up
        (ds4_msg(rx=0.75), (0.0, 0.0, 0.1)),
    ],
    "game_controller": [
        (gc_msg(), (0.0, 0.0, 0.0)),                                     # trigger at rest reads 0 here
        (gc_msg(rtrigger=-1.0), (2.7, 0.0, 0.0)),
        (gc_msg(rtrigger=-0.5), (HALF_TRIGGER, 0.0, 0.0)),               # p = (-0.5 - 0) / (-1 - 0)
        (gc_msg(righty=1.0), (0.0, -0.191, 0.0)),                        # RIGHTY up lifts
        (gc_msg(rightx=1.0), (0.0, 0.0, 0.2)),                           # RIGHTX left curls
        (gc_msg(pressed=(3,)), (0.0, -0.191, 0.0)),                      # Y / TRIANGLE
        (gc_msg(pressed=(0,)), (0.0, 0.0, 0.2)),                         # A / CROSS
    ],
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_shipped_mapping_gives_the_hand_computed_commands(name, limits):
    m = load_mapping(TELEOP / f"{name}.yaml")
    armed = {t.index for t in m.triggers}       # triggers seen at rest (the state machine tracks it)
    for (axes, buttons), want in CASES[name]:
        assert m.problem(axes, buttons) == ""
        got = m.command(axes, buttons, limits, armed)
        assert got == pytest.approx(want, abs=1e-12), ((axes, buttons), got, want)
        assert all(not (v == 0 and math.copysign(1, v) < 0) for v in got), "no -0.0 on the wire"


def test_every_shipped_file_is_tested_and_has_the_documented_buttons():
    assert sorted(p.stem for p in TELEOP.glob("*.yaml")) == sorted(SHIPPED) == sorted(CASES)
    # (deadman, e-stop, release) per file, from the index tables in the files' headers
    want = {"xbox": (4, 1, (4, 7)), "f710": (4, 1, (4, 7)), "ps4": (4, 1, (4, 9)), "game_controller": (9, 1, (9, 6))}
    for name, (deadman, estop, release) in want.items():
        m = load_mapping(TELEOP / f"{name}.yaml")
        assert (m.deadman_button, m.estop_button, m.estop_release_buttons) == (deadman, estop, release)
        assert m.estop_release_hold_s == 1.0 and m.name == name


def test_an_untouched_trigger_reading_zero_does_not_drive():
    """joy_linux / older SDL report a trigger as 0 until it is first moved: with rest +1 that is
    p = 0.5, half throttle. It counts only after it has been seen at rest."""
    m = load_mapping(TELEOP / "xbox.yaml")
    lim = ActuatorLimits((0.0, -0.191, 0.0), (2.7, 0.0, 0.2))
    core = TeleopCore(m, lim)
    assert core.on_joy(*xbox_msg(rt=0.0), 0.0).command is None          # deadman released: seen released
    out = core.on_joy(*xbox_msg(rt=0.0, pressed=(4,)), 0.05)
    assert out.command == (0.0, 0.0, 0.0)                                 # untouched trigger: no throttle
    core.on_joy(*xbox_msg(rt=1.0, pressed=(4,)), 0.10)                    # now seen at rest
    assert core.on_joy(*xbox_msg(rt=0.0, pressed=(4,)), 0.15).command == pytest.approx((HALF_TRIGGER, 0.0, 0.0))


@pytest.mark.parametrize("gap", ["timer", "late_joy", "bad_joy"])
def test_a_replugged_pad_must_show_its_triggers_at_rest_again(gap):
    """A review (2026-11-29): after driving, the pad dropped out (no Joy past joy_timeout) and came back
    with its untouched trigger reading 0 (joy_linux before the first move, or a restarted driver): a fresh
    deadman press gave half throttle, because the trigger had been seen at rest before the drop-out. Any
    gap (noticed by the timer, or only by the next Joy's arrival time) or unusable message forgets it."""
    m = load_mapping(TELEOP / "xbox.yaml")
    lim = ActuatorLimits((0.0, -0.191, 0.0), (2.7, 0.0, 0.2))
    core = TeleopCore(m, lim, joy_timeout=0.5)
    core.on_joy(*xbox_msg(), 0.0)
    assert core.on_joy(*xbox_msg(rt=-1.0, pressed=(4,)), 0.05).command == (2.7, 0.0, 0.0)
    if gap == "timer":
        core.on_timer(0.70)                                                # the timeout stops it
        t = 2.0
    elif gap == "late_joy":
        core.on_joy(*xbox_msg(rt=1.0), 0.10)                               # released, trigger at rest
        t = 0.75                                                           # next Joy 0.65 s later
    else:
        core.on_joy([0.0] * 5, [0] * 11, 0.10)                            # a message of another layout
        t = 0.15
    core.on_joy(*xbox_msg(rt=0.0), t)                                      # back, deadman released
    assert core.on_joy(*xbox_msg(rt=0.0, pressed=(4,)), t + 0.05).command == (0.0, 0.0, 0.0)
    core.on_joy(*xbox_msg(rt=1.0, pressed=(4,)), t + 0.10)                 # seen at rest again
    assert core.on_joy(*xbox_msg(rt=0.0, pressed=(4,)), t + 0.15).command == pytest.approx((HALF_TRIGGER, 0.0, 0.0))


def test_helpers_by_hand():
    assert deadzone(0.3, 0.5) == 0.0 and deadzone(-0.75, 0.5) == -0.5 and deadzone(1.0, 0.5) == 1.0
    assert deadzone(1.2, 0.0) == 1.0
    assert to_rad_s(0.5, 0.0, 2.7) == 1.35 and to_rad_s(-0.5, 0.0, 2.7) == 0.0
    assert to_rad_s(-0.5, -0.191, 0.0) == -0.0955 and to_rad_s(0.5, -0.191, 0.0) == 0.0
    assert to_rad_s(-3.0, -0.191, 0.0) == -0.191


def test_actuator_limits_check_and_clamp(limits):
    assert limits.check([1.0, -0.1, 0.1]) == ((1.0, -0.1, 0.1), False)
    assert limits.check([5.0, 0.5, -1.0]) == ((2.7, 0.0, 0.0), True)
    with pytest.raises(CommandInvalid, match="has 2 values .*expected 3"):
        limits.check([1.0, 0.0])
    with pytest.raises(CommandInvalid, match="non-finite wheels"):
        limits.check([math.nan, 0.0, 0.0])
    with pytest.raises(CommandInvalid, match="non-finite bucket"):
        limits.check([0.0, 0.0, math.inf])
    with pytest.raises(ValueError, match="contain 0"):
        ActuatorLimits((0.5, -0.191, 0.0), (2.7, 0.0, 0.2))


# ------------------------------------------------------------------ bad mapping files
BASE = {"name": "t", "deadman_button": 4, "estop_button": 1, "estop_release_buttons": [4, 7],
        "wheels": [{"axis": 5, "trigger": {"rest": 1.0, "pressed": -1.0}}]}


@pytest.mark.parametrize("change, match", [
    ({"wheel": []}, r"unknown keys \['wheel'\]"),
    ({"deadman_button": 1}, "deadman_button and estop_button are both 1"),
    ({"estop_release_buttons": [1, 7]}, "contain the estop_button 1"),
    ({"estop_release_buttons": []}, "non-empty list"),
    ({"deadman_button": -1}, r"deadman_button = -1; expected an index 0\.\.63"),
    ({"deadman_button": True}, "deadman_button = True"),
    ({"wheels": [{"axis": 5, "invert": True, "trigger": {"rest": 1.0, "pressed": -1.0}}]}, "'invert' is for sticks"),
    ({"wheels": [{"axis": 5, "trigger": {"rest": 1.0, "pressed": 0.8}}]}, "too close"),
    ({"wheels": [{"axis": 5, "scale": 0.0}]}, r"wheels\[0\]\.scale = 0.0; expected a non-zero number"),
    ({"wheels": [{"axis": 5, "deadzone": 1.0}]}, r"deadzone = 1.0; expected a number in \[0, 0.95\]"),
    ({"wheels": [{"axis": 5, "button": 2}]}, "exactly one of 'axis' or 'button'"),
    ({"wheels": [{"axis": 5, "gain": 2}]}, r"unknown keys \['gain'\]"),
    ({"boom": [{"button": 4, "value": -1.0}]}, "button 4 is the deadman button"),
    ({"boom": [{"button": 3, "value": 2.0}]}, r"boom\[0\]\.value = 2.0"),
    ({"wheels": []}, "no inputs"),
    ({"wheels": {"axis": 5}}, "expected a list of inputs"),
])
def test_bad_mapping_files_are_refused_with_the_reason(change, match):
    doc = dict(BASE, **change)
    with pytest.raises(MappingError, match=match):
        parse_mapping(doc, "bad.yaml")


def test_missing_key_and_unreadable_file(tmp_path):
    doc = dict(BASE)
    del doc["estop_button"]
    with pytest.raises(MappingError, match="bad.yaml: 'estop_button' is missing"):
        parse_mapping(doc, "bad.yaml")
    with pytest.raises(MappingError, match="cannot read"):
        load_mapping(tmp_path / "none.yaml")
    (tmp_path / "x.yaml").write_text("a: [")
    with pytest.raises(MappingError, match="not valid YAML"):
        load_mapping(tmp_path / "x.yaml")


# ------------------------------------------------------------------ the state machine
@pytest.fixture
def core(limits):
    return TeleopCore(load_mapping(TELEOP / "xbox.yaml"), limits, joy_timeout=0.5)


def drive(core, t, **kw):
    return core.on_joy(*xbox_msg(pressed=(4,) + kw.pop("pressed", ()), **kw), t)


def test_commands_need_a_fresh_deadman_press_and_release_sends_one_zero(core):
    assert drive(core, 0.0, rt=-1.0).command is None        # held since start: not a press we saw
    assert core.state == "wait_release"
    assert core.on_joy(*xbox_msg(), 0.05).command is None   # released, was not commanding: nothing
    assert drive(core, 0.10, rt=1.0).command == ZERO         # fresh press, throttle at rest
    assert drive(core, 0.15, rt=-1.0).command == (2.7, 0.0, 0.0)
    assert core.state == "commanding"
    assert core.on_joy(*xbox_msg(rt=-1.0), 0.20).command == ZERO     # released: one zero ...
    assert core.on_joy(*xbox_msg(rt=-1.0), 0.25).command is None     # ... then silence
    assert drive(core, 0.30, rt=-1.0).command == (2.7, 0.0, 0.0)     # pressed again: drives


def test_joy_stopping_gives_one_zero_after_joy_timeout_and_asks_for_a_fresh_press(core):
    core.on_joy(*xbox_msg(), 0.0)
    drive(core, 0.05, rt=1.0)
    drive(core, 0.10, rt=-1.0)
    assert core.on_timer(0.60).command is None               # 0.50 s: not yet more than joy_timeout
    out = core.on_timer(0.61)
    assert out.command == ZERO and "no Joy message for 0.51 s" in out.problem
    assert core.on_timer(0.70).command is None               # one zero, then silence
    assert drive(core, 0.80, rt=-1.0).command is None        # the controller is back, deadman held
    assert core.state == "wait_release" and core.forced_stops == 1
    core.on_joy(*xbox_msg(), 0.85)
    assert drive(core, 0.90, rt=-1.0).command == (2.7, 0.0, 0.0)


@pytest.mark.parametrize("axes, buttons, match", [
    ([0.0] * 5, [0] * 11, "Joy has 5 axes, mapping 'xbox' .* reads axis 5 .*needs at least 6"),
    ([0.0, 0.0, 1.0, 0.0, 0.0, 1.0], [0] * 7, "Joy has 7 buttons, .* reads button 7 .*needs at least 8"),
    ([0.0, 0.0, 1.0, 0.0, 0.0, math.nan], [0] * 11, "Joy axis 5 is nan; expected a finite value"),
    ([0.0, 0.0, 1.0, 0.0, 1.5, 1.0], [0] * 11, r"Joy axis 4 is 1.5, outside \[-1, 1\]"),
])
def test_malformed_joy_is_ignored_and_stops_a_commanding_operator(core, axes, buttons, match):
    core.on_joy(*xbox_msg(), 0.0)
    assert drive(core, 0.05, rt=-1.0).command == (2.7, 0.0, 0.0)
    buttons = list(buttons)
    if len(buttons) > 4:
        buttons[4] = 1                                       # the deadman still held
    out = core.on_joy(axes, buttons, 0.10)
    assert out.command == ZERO and out.estop is None
    assert core.bad_joy == 1 and core.last_was_bad
    assert re.search(match, out.problem), out.problem
    again = core.on_joy(axes, buttons, 0.15)
    assert again.command is None and again.problem          # ignored, warned (throttled by the node)
    assert drive(core, 0.20, rt=-1.0).command is None        # valid again, deadman held: fresh press needed
    assert not core.last_was_bad


def test_estop_button_engages_at_once_and_only_the_held_combination_releases(core):
    core.on_joy(*xbox_msg(), 0.0)
    drive(core, 0.05, rt=-1.0)
    out = drive(core, 0.10, rt=-1.0, pressed=(1,))
    assert out.estop is True and out.command == ZERO and core.state == "estop"
    for i in range(10):                                      # deadman + throttle: nothing moves
        assert drive(core, 0.15 + 0.05 * i, rt=-1.0).command is None
    # LB + START with B also held: not a release
    assert drive(core, 0.7, pressed=(7, 1)).estop is None
    # LB + START held, let go at 0.9 s: the hold starts again
    drive(core, 0.8, pressed=(7,))
    drive(core, 1.79, pressed=(7,))
    drive(core, 1.80)                                        # START let go
    assert core.estop
    drive(core, 2.0, pressed=(7,))
    assert drive(core, 2.99, pressed=(7,)).estop is None     # 0.99 s: not yet
    out = drive(core, 3.0, pressed=(7,))                     # 1.0 s held: released
    assert out.estop is False and out.command is None and not core.estop
    assert drive(core, 3.05, rt=-1.0).command is None        # deadman held through the release
    core.on_joy(*xbox_msg(), 3.1)
    assert drive(core, 3.15, rt=-1.0).command == (2.7, 0.0, 0.0)


def test_estop_button_counts_even_in_a_malformed_message(core):
    core.on_joy(*xbox_msg(), 0.0)
    drive(core, 0.05, rt=-1.0)
    buttons = [0] * 11
    buttons[1] = buttons[4] = 1
    out = core.on_joy([0.0] * 3, buttons, 0.1)               # too few axes, but B is readable
    assert out.estop is True and out.command == ZERO and out.problem


def test_estop_heard_on_the_topic(core):
    core.on_joy(*xbox_msg(), 0.0)
    drive(core, 0.05, rt=-1.0)
    out = core.on_estop(True)                                # `lhd estop on` while driving
    assert out.command == ZERO and out.estop is None and core.state == "estop"
    assert core.on_estop(True).command is None
    assert drive(core, 0.1, rt=-1.0).command is None
    core.on_estop(False)                                     # `lhd estop off`
    assert not core.estop and drive(core, 0.15, rt=-1.0).command is None   # fresh press needed
    core.on_joy(*xbox_msg(), 0.2)
    assert drive(core, 0.25, rt=-1.0).command == (2.7, 0.0, 0.0)
