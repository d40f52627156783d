"""`/diagnostics` from every node, the way diagnostic_aggregator and rqt_robot_monitor read it:
one DiagnosticArray per period (steady clock, so it keeps coming with use_sim_time and no
/clock), each status named `<node's fully qualified name>: <what>`, OK / WARN / ERROR with
the reason in `message`, figures as key/value pairs.

A node gives a function returning (level, message, values); the level constants are
DiagnosticStatus.OK / WARN / ERROR / STALE. The period is the ROS parameter
`diagnostic_updater.period` (s, default 1.0), the name and default of ROS's diagnostic_updater,
so `-p diagnostic_updater.period:=0.2` works as with any ROS node (the tests use it).
"""
from __future__ import annotations

from typing import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from lhd_loading_ros.ros.params import DIAGNOSTICS_PERIOD, Params, steady_timer

OK, WARN, ERROR, STALE = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", STALE: "STALE"}

Report = tuple  # (level, message, {key: value})
PERIOD_PARAM = DIAGNOSTICS_PERIOD.name           # diagnostic_updater's own parameter name


def status(name: str, hardware_id: str, level, message: str, values: dict | None = None) -> DiagnosticStatus:
    st = DiagnosticStatus()
    st.name = name
    st.hardware_id = hardware_id
    st.level = level
    st.message = message
    st.values = [KeyValue(key=str(k), value=_fmt(v)) for k, v in (values or {}).items()]
    return st


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def period_param(node) -> float:
    """The node's `diagnostic_updater.period` (s, read-only): declared and checked with the node's
    first parameters (ros/params.py DIAGNOSTICS_PERIOD), or here for a node without them."""
    if not node.has_parameter(PERIOD_PARAM):
        Params(node, [])
    return float(node.get_parameter(PERIOD_PARAM).value)


class Diagnostics:
    """Publishes the statuses given by `sources` ({what: fn() -> (level, message, values)})
    on /diagnostics every `diagnostic_updater.period` seconds (the node's parameter, default 1)."""

    def __init__(self, node, sources: dict[str, Callable[[], Report]], hardware_id: str = ""):
        self.node = node
        self.sources = dict(sources)
        self.hardware_id = hardware_id
        self.pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.period_s = period_param(node)
        self.timer = steady_timer(node, self.period_s, self.publish)
        self.last: dict[str, DiagnosticStatus] = {}

    def publish(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.node.get_clock().now().to_msg()
        fq = self.node.get_fully_qualified_name()
        for what, fn in self.sources.items():
            try:
                level, message, values = fn()
            except Exception as exc:  # noqa: BLE001 - a broken report must not stop the others
                level, message, values = ERROR, f"diagnostics failed: {exc}", {}
            st = status(f"{fq}: {what}", self.hardware_id, level, message, values)
            self.last[what] = st
            arr.status.append(st)
        self.pub.publish(arr)
