"""ROS parameters the way ROS users pass them: one declaration per parameter with its
description, range and whether it may change at run time; values of the other numeric type
accepted (`-p slope_deg:=20`, `-p rate_hz:=10`, `-p seed:=3.0`); a wrong value ends the node
with a one-line message (ValueError -> run_node -> exit status 2); a runtime `set_parameters`
either takes effect (the parameter's `on_change` runs) or is rejected with the reason.

How: each parameter is first declared dynamically typed so that rclpy's own type check cannot
end the node with a traceback, the value is coerced and checked here, and the parameter is
declared again with its static type, range and read_only flag, holding the coerced value
(so `describe_parameters` and `get_parameters` show what the node really uses). A parameter
that may change at run time must say how the node applies the change (`on_change`); all
others are read_only and rclpy refuses to set them ("Trying to set a read-only parameter").
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter


@dataclass
class Param:
    name: str
    default: Any
    description: str
    lo: float | None = None           # numbers: inclusive range
    hi: float | None = None
    choices: tuple | None = None      # strings: the accepted values
    length: int | None = None         # arrays: the required number of elements
    check: Callable[[Any], str | None] | None = None   # extra rule: returns what is wrong, or None
    on_change: Callable[[Any], None] | None = None     # runtime change allowed: how the node applies it
    dynamic_type: bool = False        # several types accepted (e.g. a number or a comma-separated list)
    log_change: bool = True           # log each runtime change (False: one set per episode would flood the log)
    warn_change: str = ""             # a safety setting: each runtime change is logged as a WARN with this text

    @property
    def kind(self) -> str:
        d = self.default
        if self.dynamic_type:
            return "any"
        if isinstance(d, bool):
            return "bool"
        if isinstance(d, int):
            return "int"
        if isinstance(d, float):
            return "float"
        if isinstance(d, str):
            return "str"
        if isinstance(d, (list, tuple)):
            return "str_list" if d and isinstance(d[0], str) else "float_list"
        raise TypeError(f"parameter {self.name}: unsupported default {d!r}")

    @property
    def read_only(self) -> bool:
        return self.on_change is None

    def expected(self) -> str:
        k = self.kind
        rng = ""
        if self.lo is not None or self.hi is not None:
            rng = f" in [{self.lo if self.lo is not None else '-inf'}, {self.hi if self.hi is not None else 'inf'}]"
        if k == "int":
            return "an integer" + rng
        if k == "float":
            return "a number" + rng
        if k == "bool":
            return "true or false"
        if k == "str":
            return f"one of {self.choices}" if self.choices else "a string"
        if k == "float_list":
            return f"{self.length or 'a list of'} finite numbers" + (f", each{rng}" if rng else "")
        if k == "str_list":
            return "a list of strings"
        return self.description

    def coerce(self, v: Any) -> Any:
        """The value in this parameter's type, or ValueError naming the parameter and what is expected."""
        k = self.kind

        def bad(why: str = "") -> ValueError:
            return ValueError(f"parameter '{self.name}' = {v!r} is invalid{(': ' + why) if why else ''}; "
                              f"expected {self.expected()}")

        if k == "any":
            out = v
        elif k == "bool":
            if not isinstance(v, bool):
                raise bad()
            out = v
        elif k == "int":
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise bad()
            if isinstance(v, float) and not (math.isfinite(v) and v.is_integer()):
                raise bad()
            out = int(v)
        elif k == "float":
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise bad()
            out = float(v)
        elif k == "str":
            if not isinstance(v, str):
                raise bad()
            if self.choices and v not in self.choices:
                raise bad()
            out = v
        elif k == "float_list":
            try:
                out = [float(x) for x in v]
            except (TypeError, ValueError):
                raise bad() from None
            if any(isinstance(x, (bool, str)) for x in v) or not all(math.isfinite(x) for x in out):
                raise bad()
            if self.length is not None and len(out) != self.length:
                raise bad(f"{len(out)} elements")
        else:   # str_list
            if isinstance(v, str) or not all(isinstance(x, str) for x in v):
                raise bad()
            out = list(v)
        if k in ("int", "float") or k == "float_list":
            vals = out if k == "float_list" else [out]
            if any((self.lo is not None and x < self.lo) or (self.hi is not None and x > self.hi) for x in vals):
                raise bad("out of range")
        if self.check is not None:
            why = self.check(out)
            if why:
                raise ValueError(f"parameter '{self.name}' = {v!r} is invalid: {why}")
        return out

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(name=self.name, description=self.description, read_only=self.read_only,
                                dynamic_typing=self.dynamic_type)
        extra = []
        if self.choices:
            extra.append(f"one of {', '.join(map(str, self.choices))}")
        if self.length:
            extra.append(f"{self.length} elements")
        if self.read_only:
            extra.append("fixed at start")
        d.additional_constraints = "; ".join(extra)
        if self.kind == "float" and (self.lo is not None or self.hi is not None):
            d.floating_point_range = [FloatingPointRange(from_value=float(self.lo if self.lo is not None else -1e308),
                                                         to_value=float(self.hi if self.hi is not None else 1e308),
                                                         step=0.0)]
        if self.kind == "int" and (self.lo is not None or self.hi is not None):
            d.integer_range = [IntegerRange(from_value=int(self.lo if self.lo is not None else -2**63),
                                            to_value=int(self.hi if self.hi is not None else 2**63 - 1), step=1)]
        return d


# Every node's `/diagnostics` period (ros/diagnostics.py), under ROS's diagnostic_updater name and
# default; declared with whichever Params a node creates first.
DIAGNOSTICS_PERIOD = Param("diagnostic_updater.period", 1.0, "s between two /diagnostics messages of this node",
                           lo=0.01, hi=60.0)


class Params:
    """The declared, checked parameters of one node: `params["rate_hz"]`, always of the declared type."""

    def __init__(self, node, specs: list[Param]):
        self.node = node
        if not node.has_parameter(DIAGNOSTICS_PERIOD.name):   # with the node's first parameters: a bad
            specs = [*specs, DIAGNOSTICS_PERIOD]               # value ends it before it does anything
        self.specs = {s.name: s for s in specs}
        self.values: dict[str, Any] = {}
        for s in specs:
            self.values[s.name] = self._declare(s)
        # rclpy concatenates what every pre-set callback returns, so a node gets one set of
        # callbacks that serves all its Params (a node may declare some parameters first, e.g.
        # `config`, and the rest once it has read them)
        group = getattr(node, "_lhd_params_group", None)
        if group is None:
            group = node._lhd_params_group = _Group()
            node.add_pre_set_parameters_callback(group.pre_set)
            node.add_on_set_parameters_callback(group.on_set)
            node.add_post_set_parameters_callback(group.post_set)
        group.members.append(self)

    def __getitem__(self, name: str) -> Any:
        return self.values[name]

    def _declare(self, s: Param) -> Any:
        node = self.node
        # first pass: any type, so that rclpy cannot refuse an int for a float with a traceback
        loose = ParameterDescriptor(dynamic_typing=True)
        try:
            raw = node.declare_parameter(s.name, s.default, loose).value
        except InvalidParameterValueException as exc:
            raise ValueError(f"parameter '{s.name}' is invalid ({exc}); expected {s.expected()}") from None
        if raw is None:     # `-p name:=` with nothing, or a YAML null (rcl reads an empty list `[]` so too)
            hint = {"str_list": " (an empty list `[]` reaches a node as no value, rcl cannot type it: write [''] for none)",
                    "float_list": " (an empty list `[]` reaches a node as no value, rcl cannot type it)"}.get(s.kind, "")
            raise ValueError(f"parameter '{s.name}' has no value; expected {s.expected()}{hint}")
        value = s.coerce(raw)
        node.undeclare_parameter(s.name)
        node.declare_parameter(s.name, _as_param_value(s, value), s.descriptor(), ignore_override=True)
        return value


class _Group:
    """The parameter callbacks of one node, over all its Params."""

    def __init__(self):
        self.members: list[Params] = []

    def _find(self, name: str):
        for m in self.members:
            if name in m.specs:
                return m, m.specs[name]
        return None, None

    def pre_set(self, params: list[Parameter]) -> list[Parameter]:
        out = []
        for p in params:
            _, s = self._find(p.name)
            if s is not None and s.kind == "float" and p.type_ == Parameter.Type.INTEGER:
                p = Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
            elif s is not None and s.kind == "int" and p.type_ == Parameter.Type.DOUBLE and float(p.value).is_integer():
                p = Parameter(p.name, Parameter.Type.INTEGER, int(p.value))
            out.append(p)
        return out

    def on_set(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            _, s = self._find(p.name)
            if s is None:
                continue
            if s.read_only:   # rclpy refuses these before us; kept for clarity
                return SetParametersResult(successful=False, reason=f"parameter '{p.name}' cannot change at run time")
            try:
                s.coerce(p.value)
            except ValueError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def post_set(self, params: list[Parameter]) -> None:
        for p in params:
            m, s = self._find(p.name)
            if s is None or s.on_change is None:
                continue
            value = s.coerce(p.value)
            m.values[p.name] = value
            s.on_change(value)
            if s.warn_change:
                m.node.get_logger().warn(f"parameter '{p.name}' set to {value!r} at run time: {s.warn_change}")
            elif s.log_change:
                m.node.get_logger().info(f"parameter '{p.name}' set to {value!r}")


def _as_param_value(s: Param, value):
    if s.kind == "float_list":
        return [float(x) for x in value]
    return value


def topic_prefix(node, namespace_prefix: str) -> str:
    """Where a node's /lhd topics live: `namespace_prefix` (default /lhd) when the node runs in
    the root namespace; the node's namespace when one is given (`--ros-args -r __ns:=/lhd2`
    puts every topic of the machine under /lhd2, so two machines, or a simulated and a real
    one, share a domain)."""
    ns = node.get_namespace()
    if ns and ns != "/":
        return ns.rstrip("/")
    p = namespace_prefix.rstrip("/")
    p = p if p.startswith("/") else "/" + p
    from rclpy.validate_topic_name import validate_topic_name
    from rclpy.exceptions import InvalidTopicNameException

    try:
        validate_topic_name(p + "/x")
    except InvalidTopicNameException as exc:
        # a ValueError: run_node ends the node with this one line and exit status 2
        raise ValueError(f"parameter 'namespace_prefix' = {namespace_prefix!r} is invalid: expected a ROS topic "
                         "prefix such as /lhd (letters, digits and underscores between slashes, no token "
                         f"starting with a digit): {str(exc).splitlines()[0].rstrip(':')}") from None
    return p


def steady_timer(node, period_s: float, callback):
    """A timer on the steady clock. Safety and housekeeping timers (watchdogs, staleness,
    diagnostics, the simulator's own real-time loop) must run with `use_sim_time:=true` too,
    where the node's clock only moves when /clock is published, or a node would wait on itself."""
    from rclpy.clock import Clock, ClockType

    return node.create_timer(period_s, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))


DISCOVERY_WAIT_ENV = "LHD_DISCOVERY_WAIT_S"
DISCOVERY_WAIT_DEFAULT_S = 3.0


def discovery_wait_s() -> float:
    """How long a launcher listens for an LHD stack already running on its domain before it starts
    its own (DDS discovery of existing participants): LHD_DISCOVERY_WAIT_S, default 3 s. On one
    host Fast DDS discovers in well under a second; a network with many participants or lossy
    multicast may need more. A value that is not a number >= 0 is an error naming the variable."""
    import os

    raw = os.environ.get(DISCOVERY_WAIT_ENV, "")
    if raw.strip() == "":
        return DISCOVERY_WAIT_DEFAULT_S
    try:
        v = float(raw)
    except ValueError:
        v = float("nan")
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{DISCOVERY_WAIT_ENV}={raw!r}; expected seconds >= 0 (default {DISCOVERY_WAIT_DEFAULT_S:g})")
    return v
