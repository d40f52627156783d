"""Gamepad teleoperation without ROS: a per-controller mapping (YAML, config/teleop/*.yaml) from
sensor_msgs/Joy axes and buttons to [u_wheels, u_boom, u_bucket] rad/s, and the deadman /
e-stop state machine the teleop node runs (docs/teleop.md).

Mapping. Each actuator sums its inputs, each a fraction of the actuator's full speed:
  stick    {axis, scale, invert, deadzone}: v = axes[axis] (negated if invert); |v| <= deadzone
           gives 0, beyond it the rest of the travel is rescaled to 0..1 (as the joy driver does
           for its own deadzone), times scale;
  trigger  {axis, trigger: {rest, pressed}, scale, deadzone}: press p = (v - rest) / (pressed - rest)
           in [0, 1] (joy_node / joy_linux triggers rest at +1 and read -1 fully pressed; the
           game_controller_node's rest at 0); a trigger counts only after it has been seen at
           rest once, because joy_linux and older SDL report an untouched trigger as 0, which
           would read as half pressed (ros-drivers/joystick_drivers issue 155);
  button   {button, value}: value while held (the boom and bucket valves are ternary: a button
           asks for full speed).
The sum s is clamped to [-1, 1] and mapped onto the task's actuator range (ActuatorLimits, the
same as the actor's actions): s > 0 gives s * hi, s < 0 gives s * |lo|, so a direction the
range does not have (reverse, lowering the boom, tipping the bucket forward) gives 0.

State machine (TeleopCore). Commands flow only while the deadman is held, and only after a
fresh press: the deadman must be seen released (in a valid Joy message, e-stop off) before a
press engages. Releasing it gives one zero command, then silence (teleop_twist_joy's
publish-zero-on-release). A forced stop (Joy messages stopping for joy_timeout, a malformed
Joy, the e-stop) also gives one zero and asks for a fresh press. The e-stop button engages the
e-stop at once, whatever else is wrong with the message; only the release combination
(estop_release_buttons held together, without the e-stop button, for estop_release_hold_s,
seen in Joy messages: a driver publishing only on change must autorepeat) releases it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from lhd_loading_ros.policy.actuator_limits import ZERO, ActuatorLimits
from lhd_loading_ros.task.actions import ACT_NAMES

MAX_INDEX = 63             # Joy messages of real devices carry far fewer axes / buttons
AXIS_TOLERANCE = 1e-3      # drivers publish float32 in [-1, 1]; anything further out is not a joystick
REST_TOLERANCE = 0.05      # a trigger within this press fraction of its rest has been seen at rest
SHIPPED = ("xbox", "ps4", "f710", "game_controller")

_TOP_KEYS = {"name", "controller", "driver", "deadman_button", "estop_button", "estop_release_buttons",
             "estop_release_hold_s", *ACT_NAMES}
_AXIS_KEYS = {"axis", "scale", "invert", "deadzone", "trigger", "label"}
_BUTTON_KEYS = {"button", "value", "label"}


class MappingError(ValueError):
    """A mapping file that cannot be used; the message names the file, the key and what is expected."""


@dataclass(frozen=True)
class AxisInput:
    index: int
    scale: float = 1.0
    invert: bool = False
    deadzone: float = 0.0
    trigger: tuple[float, float] | None = None     # (rest, pressed) for a trigger axis
    label: str = ""

    def press(self, v: float) -> float:
        """A trigger's press fraction in [0, 1] before the deadzone."""
        rest, pressed = self.trigger
        return min(max((v - rest) / (pressed - rest), 0.0), 1.0)

    def fraction(self, v: float, armed: bool) -> float:
        if self.trigger is not None:
            return self.scale * deadzone(self.press(v), self.deadzone) if armed else 0.0
        return self.scale * deadzone(-v if self.invert else v, self.deadzone)


@dataclass(frozen=True)
class ButtonInput:
    index: int
    value: float
    label: str = ""


def deadzone(v: float, dz: float) -> float:
    """0 inside the deadzone; beyond it the remaining travel rescaled to reach +-1 at the end."""
    a = abs(v)
    if a <= dz:
        return 0.0
    return math.copysign(min((a - dz) / (1.0 - dz), 1.0), v)


def to_rad_s(s: float, lo: float, hi: float) -> float:
    """A fraction of full speed in [-1, 1] -> rad/s in [lo, hi] (lo <= 0 <= hi)."""
    s = min(max(s, -1.0), 1.0)
    u = s * hi if s > 0.0 else s * -lo
    return min(max(u, lo), hi) + 0.0      # + 0.0: no -0.0 on the wire


@dataclass(frozen=True)
class JoyMapping:
    name: str
    deadman_button: int
    estop_button: int
    estop_release_buttons: tuple[int, ...]
    estop_release_hold_s: float
    inputs: dict = field(default_factory=dict)   # actuator name -> tuple of AxisInput / ButtonInput
    controller: str = ""
    driver: str = ""
    source: str = ""

    @property
    def axes_used(self) -> list[int]:
        return sorted({i.index for ins in self.inputs.values() for i in ins if isinstance(i, AxisInput)})

    @property
    def buttons_used(self) -> list[int]:
        b = {self.deadman_button, self.estop_button, *self.estop_release_buttons}
        b |= {i.index for ins in self.inputs.values() for i in ins if isinstance(i, ButtonInput)}
        return sorted(b)

    @property
    def needed_axes(self) -> int:
        return max(self.axes_used, default=-1) + 1

    @property
    def needed_buttons(self) -> int:
        return max(self.buttons_used) + 1

    @property
    def triggers(self) -> list[AxisInput]:
        return [i for ins in self.inputs.values() for i in ins if isinstance(i, AxisInput) and i.trigger is not None]

    def problem(self, axes, buttons) -> str:
        """What makes this Joy message unusable with this mapping ('' when it is fine)."""
        where = f"mapping '{self.name}' ({self.source or 'in memory'})"
        if len(axes) < self.needed_axes:
            return (f"Joy has {len(axes)} axes, {where} reads axis {self.needed_axes - 1} (needs at least "
                    f"{self.needed_axes}): another controller or driver? compare `ros2 topic echo /joy` with the mapping")
        if len(buttons) < self.needed_buttons:
            return (f"Joy has {len(buttons)} buttons, {where} reads button {self.needed_buttons - 1} (needs at least "
                    f"{self.needed_buttons}): another controller or driver? compare `ros2 topic echo /joy` with the mapping")
        for i in self.axes_used:
            v = float(axes[i])
            if not math.isfinite(v):
                return f"Joy axis {i} is {v}; expected a finite value in [-1, 1]"
            if abs(v) > 1.0 + AXIS_TOLERANCE:
                return f"Joy axis {i} is {v:g}, outside [-1, 1]; expected a normalised joystick axis"
        return ""

    def command(self, axes, buttons, limits: ActuatorLimits, armed: set | frozenset = frozenset()) -> tuple:
        """[u_wheels, u_boom, u_bucket] rad/s for a valid Joy message (see problem()); `armed`:
        the trigger axes seen at rest so far."""
        out = []
        for k, name in enumerate(ACT_NAMES):
            s = 0.0
            for inp in self.inputs.get(name, ()):
                if isinstance(inp, AxisInput):
                    s += inp.fraction(float(axes[inp.index]), inp.index in armed)
                elif buttons[inp.index]:
                    s += inp.value
            out.append(to_rad_s(s, limits.lo[k], limits.hi[k]))
        return tuple(out)

    def rests(self, axes) -> set:
        """Trigger axes at rest in this (valid) message."""
        return {t.index for t in self.triggers if t.press(float(axes[t.index])) <= max(t.deadzone, REST_TOLERANCE)}


# ------------------------------------------------------------------ parsing
def _index(v, where: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= MAX_INDEX:
        raise MappingError(f"{where} = {v!r}; expected an index 0..{MAX_INDEX} into Joy axes / buttons")
    return v


def _number(v, where: str, lo: float, hi: float, nonzero: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi \
            or (nonzero and v == 0):
        raise MappingError(f"{where} = {v!r}; expected a {'non-zero ' if nonzero else ''}number in [{lo:g}, {hi:g}]")
    return float(v)


def _input(d, where: str):
    if not isinstance(d, dict):
        raise MappingError(f"{where} = {d!r}; expected a mapping with 'axis' or 'button'")
    if ("axis" in d) == ("button" in d):
        raise MappingError(f"{where} must have exactly one of 'axis' or 'button', got keys {sorted(d)}")
    if "button" in d:
        extra = set(d) - _BUTTON_KEYS
        if extra:
            raise MappingError(f"{where}: unknown keys {sorted(extra)}; a button input has {sorted(_BUTTON_KEYS)}")
        return ButtonInput(_index(d["button"], f"{where}.button"),
                           _number(d.get("value"), f"{where}.value", -1.0, 1.0, nonzero=True), str(d.get("label", "")))
    extra = set(d) - _AXIS_KEYS
    if extra:
        raise MappingError(f"{where}: unknown keys {sorted(extra)}; an axis input has {sorted(_AXIS_KEYS)}")
    invert = d.get("invert", False)
    if not isinstance(invert, bool):
        raise MappingError(f"{where}.invert = {invert!r}; expected true or false")
    trig = d.get("trigger")
    if trig is not None:
        if not isinstance(trig, dict) or set(trig) != {"rest", "pressed"}:
            raise MappingError(f"{where}.trigger = {trig!r}; expected {{rest: R, pressed: P}} (the axis value "
                               "released and fully pressed)")
        rest = _number(trig["rest"], f"{where}.trigger.rest", -1.0, 1.0)
        pressed = _number(trig["pressed"], f"{where}.trigger.pressed", -1.0, 1.0)
        if abs(pressed - rest) < 0.5:
            raise MappingError(f"{where}.trigger: rest {rest:g} and pressed {pressed:g} are too close; a trigger "
                               "travels at least 0.5")
        if invert:
            raise MappingError(f"{where}: 'invert' is for sticks; a trigger's direction is given by rest and pressed")
        trig = (rest, pressed)
    return AxisInput(_index(d["axis"], f"{where}.axis"), _number(d.get("scale", 1.0), f"{where}.scale", -10.0, 10.0,
                                                                  nonzero=True),
                     invert, _number(d.get("deadzone", 0.0), f"{where}.deadzone", 0.0, 0.95), trig,
                     str(d.get("label", "")))


def parse_mapping(doc, source: str = "") -> JoyMapping:
    """A validated JoyMapping from a loaded YAML document; MappingError naming the problem."""
    pre = f"{source}: " if source else ""
    try:
        if not isinstance(doc, dict):
            raise MappingError(f"expected a mapping at the top, got {type(doc).__name__}")
        extra = set(doc) - _TOP_KEYS
        if extra:
            raise MappingError(f"unknown keys {sorted(extra)}; expected {sorted(_TOP_KEYS)}")
        for key in ("name", "deadman_button", "estop_button", "estop_release_buttons"):
            if key not in doc:
                raise MappingError(f"'{key}' is missing")
        deadman = _index(doc["deadman_button"], "deadman_button")
        estop = _index(doc["estop_button"], "estop_button")
        rel = doc["estop_release_buttons"]
        if not isinstance(rel, list) or not rel:
            raise MappingError(f"estop_release_buttons = {rel!r}; expected a non-empty list of button indices")
        release = tuple(_index(b, f"estop_release_buttons[{i}]") for i, b in enumerate(rel))
        hold = _number(doc.get("estop_release_hold_s", 1.0), "estop_release_hold_s", 0.0, 10.0)
        if deadman == estop:
            raise MappingError(f"deadman_button and estop_button are both {deadman}")
        if estop in release:
            raise MappingError(f"estop_release_buttons {list(release)} contain the estop_button {estop}: "
                               "the release must not be the button that engages it")
        inputs = {}
        for name in ACT_NAMES:
            raw = doc.get(name, [])
            if not isinstance(raw, list):
                raise MappingError(f"{name} = {raw!r}; expected a list of inputs ({{axis: ...}} or {{button: ...}})")
            inputs[name] = tuple(_input(d, f"{name}[{i}]") for i, d in enumerate(raw))
            for inp in inputs[name]:
                if isinstance(inp, ButtonInput) and inp.index in (deadman, estop):
                    raise MappingError(f"{name}: button {inp.index} is the {'deadman' if inp.index == deadman else 'estop'}"
                                       " button; it cannot also move an actuator")
        if not any(inputs.values()):
            raise MappingError("no inputs: wheels, boom and bucket are all empty")
        return JoyMapping(str(doc["name"]), deadman, estop, release, hold, inputs, str(doc.get("controller", "")),
                          str(doc.get("driver", "")), source)
    except MappingError as exc:
        raise MappingError(f"{pre}{exc}") from None


def load_mapping(path) -> JoyMapping:
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise MappingError(f"cannot read the teleop mapping {p}: {exc}") from None
    except yaml.YAMLError as exc:
        raise MappingError(f"{p} is not valid YAML: {exc}") from None
    return parse_mapping(doc, str(p))


# ------------------------------------------------------------------ state machine
@dataclass
class TeleopOutput:
    command: tuple | None = None    # publish on <prefix>/cmd/teleop
    estop: bool | None = None       # publish on <prefix>/estop (latched)
    problem: str = ""               # a bad Joy or a dead controller: for the throttled warning


class TeleopCore:
    """Joy messages and the clock in, commands and e-stop changes out (module docstring)."""

    def __init__(self, mapping: JoyMapping, limits: ActuatorLimits, joy_timeout: float = 0.5):
        self.mapping = mapping
        self.limits = limits
        self.joy_timeout = joy_timeout
        self.estop = False
        self.commanding = False
        self.may_engage = False          # the deadman has been seen released since the last stop
        self.deadman_held = False
        self.armed: set = set()          # trigger axes seen at rest
        self.last_joy: float | None = None   # arrival of the latest valid Joy
        self.release_since: float | None = None
        self.joy_messages = 0
        self.bad_joy = 0
        self.last_problem = ""
        self.last_was_bad = False        # the latest Joy message was unusable
        self.commands = 0
        self.forced_stops = 0

    @property
    def state(self) -> str:
        if self.estop:
            return "estop"
        if self.commanding:
            return "commanding"
        if self.deadman_held:
            return "wait_release"        # held, but a fresh press is needed first
        return "idle"

    def _stop(self, out: TeleopOutput, forced: bool) -> None:
        if self.commanding:
            out.command = ZERO
            self.commanding = False
            if forced:
                self.forced_stops += 1
        if forced:
            self.may_engage = False

    def _engage_estop(self, out: TeleopOutput) -> None:
        self.estop = True
        self.release_since = None
        self._stop(out, forced=True)

    def on_joy(self, axes, buttons, now: float) -> TeleopOutput:
        out = TeleopOutput()
        m = self.mapping
        self.joy_messages += 1
        # the e-stop first: honoured whenever its button can be read, whatever else is wrong
        if m.estop_button < len(buttons) and buttons[m.estop_button] and not self.estop:
            self._engage_estop(out)
            out.estop = True
        problem = m.problem(axes, buttons)
        if problem:
            self.bad_joy += 1
            self.last_problem = out.problem = problem
            self.last_was_bad = True
            self.release_since = None
            self.armed.clear()                  # what reads after it may be another driver's state
            self._stop(out, forced=True)
            return out
        if self.last_joy is not None and now - self.last_joy > self.joy_timeout:
            # a gap: the pad or its driver may have been replugged / restarted between two timer ticks,
            # and an untouched trigger may read 0 again (half throttle): it must be seen at rest anew
            self.armed.clear()
        self.last_joy = now
        self.last_was_bad = False
        self.armed |= m.rests(axes)
        self.deadman_held = bool(buttons[m.deadman_button])
        if self.estop:
            held = all(buttons[b] for b in m.estop_release_buttons) and not buttons[m.estop_button]
            if not held:
                self.release_since = None
            elif self.release_since is None:
                self.release_since = now
            self._maybe_release(out, now)
            return out
        if not self.deadman_held:
            self._stop(out, forced=False)       # released: one zero, then silence
            self.may_engage = True
            return out
        if not self.commanding:
            if not self.may_engage:
                return out                      # held since before a stop: release and press again
            self.commanding = True
        out.command = m.command(axes, buttons, self.limits, self.armed)
        self.commands += 1
        return out

    def _maybe_release(self, out: TeleopOutput, now: float) -> None:
        if self.release_since is not None and now - self.release_since >= self.mapping.estop_release_hold_s:
            self.estop = False
            self.release_since = None
            self.may_engage = False             # the deadman is held in the combination: press it anew
            out.estop = False

    def on_timer(self, now: float) -> TeleopOutput:
        out = TeleopOutput()
        if self.last_joy is None:
            return out
        age = now - self.last_joy
        if age > self.joy_timeout:
            # the pad is gone (unplugged, driver stopped): a reconnected one reports an untouched trigger as
            # 0 on some drivers, which with rest +1 is half throttle; the triggers must be seen at rest anew
            self.armed.clear()
        if self.commanding and age > self.joy_timeout:
            self._stop(out, forced=True)
            self.deadman_held = False
            out.problem = (f"no Joy message for {age:.2f} s (joy_timeout {self.joy_timeout:g} s) while the deadman was "
                           "held: stopped; release and press the deadman again")
        return out

    def on_estop(self, engaged: bool) -> TeleopOutput:
        """The e-stop as heard on the topic (this node's own button, the CLI, another operator)."""
        out = TeleopOutput()
        if engaged and not self.estop:
            self._engage_estop(out)
        elif not engaged and self.estop:
            self.estop = False
            self.release_since = None
            self.may_engage = False
        return out
