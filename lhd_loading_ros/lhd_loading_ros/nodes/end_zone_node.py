"""`ros2 run lhd_loading_ros end_zone_node`: the end zone of the real pile (docs/end_zone.md).

source = lidar (default)
  In:  <prefix>/pile/slope_stamped  geometry_msgs/Vector3Stamped from the LiDAR slope node:
       x = alpha (rad), y = toe x (m, pile frame {M}), z = RMS fit residual (m)
  The zones of the intact wedge whose face rises at alpha from the toe, holding the nominal bulk
  density (config pile.density_min/max midpoint, or the `density` parameter):
  Zones.for_measured_pile, the simulator's zone rules (task/zones.py).
source = surveyed
  The same from a YAML file (`surveyed_file`): the end zone, the 8 zone limits, or a surveyed
  pile (slope_deg, toe_x, optional density). Read once at start; a bad file ends the node
  (exit 2, one line saying what is wrong).

Out (latched: LATCHED_QOS, reliable + transient local, keep-last 1; the pile changes once per
attempt and a supervisor or policy node started later must still get it):
  <prefix>/pile/end_zone  std_msgs/Float64MultiArray [x_min, x_max, z_min] (the topic contract)
  <prefix>/pile/zones     std_msgs/Float64MultiArray the 8 limits of task.zones.Zones (as_list)
and /diagnostics (`zones`). The first estimate is always published; later ones only when x_min,
x_max or x_cutoff moved by more than `republish_threshold` from the published one
(task/end_zone.Republisher). A bad input (NaN, slope outside [slope_min_deg, slope_max_deg],
|toe x| > toe_x_limit) publishes nothing: the last good zones stay latched, /diagnostics says
ERROR with the value and what is expected, and a throttled log line. No slope for stale_warn_s:
WARN (the latched zones keep their meaning: the pile has not moved because the LiDAR is quiet).
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict

from geometry_msgs.msg import Vector3Stamped
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from std_msgs.msg import Float64MultiArray

from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, topic_prefix
from lhd_loading_ros.ros.qos import LATCHED_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.end_zone import (DENSITY_RANGE, InputLimits, Republisher, density_problem, largest_change,
                                           load_survey, nominal_density, zones_of_pile)
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.zones import ESTIMATE_SLOPE_RANGE_DEG

SOURCES = ("lidar", "surveyed")
OVERTAKEN_NS = 1_000_000_000    # a sample this much older (source time) than the one taken came late


class EndZoneNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("end_zone_node", **node_kwargs)
        self.survey = None
        self.basis = None               # (alpha, toe_x, residual, stamp) of the last good measured pile
        # the parameter file first: it gives the nominal density
        self.cfg = load_config(Params(self, [Param("config", "", "lhd_params.yaml to use; empty: found "
                                                   "automatically (LHD_CONFIG, then the package's)")])["config"] or None)
        self.tp = TaskParams.from_config(self.cfg)
        self.p = Params(self, [
            Param("source", "lidar", "lidar: from <prefix>/pile/slope_stamped; surveyed: from surveyed_file",
                  choices=SOURCES),
            Param("surveyed_file", "", "YAML file of a surveyed end zone or pile (source surveyed); "
                  "see config/end_zone_surveyed.example.yaml"),
            Param("density", 0.0, f"nominal bulk density (kg/m^3) of the pile; 0: the config's "
                  f"(pile.density_min/max midpoint, {nominal_density(self.cfg):g})", lo=0.0, hi=DENSITY_RANGE[1],
                  check=self._density_check, on_change=lambda v: self._recompute(force=True)),
            Param("republish_threshold", 0.02, "m: a new estimate is published when x_min, x_max or x_cutoff "
                  "moved by more than this from the published one (the first is always published)", lo=0.0, hi=1.0,
                  on_change=self._set_threshold),
            Param("slope_min_deg", ESTIMATE_SLOPE_RANGE_DEG[0], "smallest pile slope accepted (deg)", lo=0.5, hi=89.5,
                  check=lambda v: self._range_problem(v, None)),
            Param("slope_max_deg", ESTIMATE_SLOPE_RANGE_DEG[1], "largest pile slope accepted (deg)", lo=0.5, hi=89.5,
                  check=lambda v: self._range_problem(None, v)),
            Param("toe_x_limit", 5.0, "m: a toe farther than this from the pile frame's origin is refused",
                  lo=0.01, hi=100.0),
            Param("pile_frame_id", "pile", "frame the slope's toe must be given in (the LiDAR node's frame_id); "
                  "a slope stamped in another frame is refused (an empty frame_id is taken)"),
            Param("stale_warn_s", 10.0, "s without a slope (source lidar) before /diagnostics says WARN",
                  lo=0.1, hi=3600.0),
            Param("namespace_prefix", "/lhd", "topic prefix in the root namespace (under a namespace, the "
                  "namespace is the prefix)"),
        ])
        p = self.p
        self.limits = InputLimits(math.radians(p["slope_min_deg"]), math.radians(p["slope_max_deg"]),
                                  p["toe_x_limit"])
        self.source = p["source"]
        self.republisher = Republisher(p["republish_threshold"])
        self.current = None             # the latest good estimate (published or not)
        self.problem: str | None = None     # why the latest input gave no zones
        self.received = self.rejected = self.published = 0
        self.last_input: float | None = None   # monotonic arrival of the latest slope
        self._source_ns: int | None = None
        ns = topic_prefix(self, p["namespace_prefix"])
        self.pub_end = self.create_publisher(Float64MultiArray, f"{ns}/pile/end_zone", LATCHED_QOS)
        self.pub_zones = self.create_publisher(Float64MultiArray, f"{ns}/pile/zones", LATCHED_QOS)

        if self.source == "surveyed":
            if not p["surveyed_file"]:
                raise ValueError("parameter 'surveyed_file' is empty: source surveyed needs the YAML file of the "
                                 "surveyed end zone or pile (config/end_zone_surveyed.example.yaml)")
            self.survey = load_survey(p["surveyed_file"], self.tp, self.limits)
            self._recompute(force=True)      # a bad combination (density too low) ends the node: exit 2
        else:
            if p["surveyed_file"]:
                raise ValueError(f"parameter 'surveyed_file' = {p['surveyed_file']!r} is set but source is lidar: "
                                 f"set source:=surveyed to use it, or leave surveyed_file empty")
            # QoS: the LiDAR node publishes slope_stamped latched (reliable + transient local); only a
            # transient-local subscription gets the value it sent before this node started, and DDS
            # does not match that subscription with a volatile publisher (a test, `ros2 topic pub`),
            # which the second, sensor-data (best effort) one takes. A latched sample arrives through
            # both; the copy is dropped by its source time (_on_slope).
            quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _: None)
            for qos, events in ((qos_profile_sensor_data, None), (LATCHED_QOS, quiet)):
                self.create_subscription(Vector3Stamped, f"{ns}/pile/slope_stamped", self._on_slope, qos,
                                         event_callbacks=events)
        self.topic = f"{ns}/pile/slope_stamped"
        self.diag = Diagnostics(self, {"zones": self._report})
        d, d_src = self.density()
        self.get_logger().info(f"end zone node up: source {self.source}"
                               + (f" ({self.survey.path})" if self.survey is not None else f", waiting for {self.topic}")
                               + ("" if self.survey is not None and not self.survey.is_pile
                                  else f"; bulk density {d:g} kg/m^3 ({d_src})")
                               + f"; publishing {ns}/pile/end_zone and {ns}/pile/zones, latched")

    # ------------------------------------------------------------------ parameters
    def _range_problem(self, lo_deg, hi_deg) -> str | None:
        other = "slope_max_deg" if hi_deg is None else "slope_min_deg"
        if not self.has_parameter(other):
            return None     # declared next; checked then
        v = self.get_parameter(other).value
        lo, hi = (lo_deg, v) if hi_deg is None else (v, hi_deg)
        return None if lo < hi else f"needs slope_min_deg < slope_max_deg (got {lo:g} and {hi:g})"

    def _density_check(self, v: float) -> str | None:
        """0 (the config's) or a bulk density in range that gives an end zone for the pile in use."""
        if v == 0.0:
            d = nominal_density(self.cfg)
        else:
            why = density_problem(v)
            if why:
                return f"{why}, or 0 for the config's"
            d = v
        if not hasattr(self, "republisher"):
            return None     # at start: the pile comes later
        try:
            self._estimate(d)
        except ValueError as exc:
            return str(exc)
        return None

    def _set_threshold(self, v: float) -> None:
        self.republisher.threshold = v
        self._publish_if_due(force=False)

    def density(self) -> tuple[float, str]:
        """(kg/m^3, where it came from): the parameter, else the surveyed file's, else the config's."""
        if self.p["density"] > 0.0:
            return self.p["density"], "parameter density"
        if self.survey is not None and self.survey.density is not None:
            return self.survey.density, f"surveyed_file {self.survey.path}"
        return nominal_density(self.cfg), "config pile.density_min/max midpoint"

    # ------------------------------------------------------------------ estimates
    def _estimate(self, density: float):
        """The zones of the pile in use with `density` (None before the first good slope)."""
        if self.survey is not None:
            return self.survey.zones_for(density, self.tp)
        if self.basis is None:
            return None
        alpha, toe_x = self.basis[:2]
        return zones_of_pile(alpha, toe_x, density, self.tp)

    def _recompute(self, force: bool) -> None:
        z = self._estimate(self.density()[0])
        if z is not None:
            self.current = z
            self._publish_if_due(force)

    def _publish_if_due(self, force: bool) -> None:
        if self.current is None or not self.republisher.offer(self.current, force=force):
            return
        z = self.current
        self.pub_end.publish(Float64MultiArray(data=[z.x_min, z.x_max, z.z_min]))
        self.pub_zones.publish(Float64MultiArray(data=z.as_list()))
        self.published += 1
        self.get_logger().info(f"end zone x {z.x_min:.3f}-{z.x_max:.3f} m, z > {z.z_min:g} m; cutoff "
                               f"{z.x_cutoff:.3f} m ({self._basis_text()})")

    def _on_slope(self, msg: Vector3Stamped, info) -> None:
        src = info["source_timestamp"]
        if self._source_ns is not None and 0 <= self._source_ns - src < OVERTAKEN_NS:
            return          # the same sample through the other subscription, or one overtaken by a newer
        self._source_ns = src
        self.last_input = time.monotonic()
        self.received += 1
        alpha, toe_x, residual = msg.vector.x, msg.vector.y, msg.vector.z
        why = self.limits.problem(alpha, toe_x, residual)
        frame = self.p["pile_frame_id"]
        if why is None and msg.header.frame_id not in ("", frame):
            # the toe is a position: in another frame it is another place (a review found a slope
            # stamped in the LiDAR's frame taken)
            why = f"frame_id {msg.header.frame_id!r}; expected the toe in the pile frame {frame!r} (pile_frame_id)"
        if why is None:
            try:
                z = zones_of_pile(alpha, toe_x, self.density()[0], self.tp)
            except ValueError as exc:
                why = str(exc)
        if why is not None:
            self.rejected += 1
            self.problem = f"{self.topic}: {why}"
            self.get_logger().warn(f"no end zone published: {self.problem}; the last good one stays latched",
                                   throttle_duration_sec=2.0)
            return
        self.problem = None
        self.basis = (alpha, toe_x, residual, f"{msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d}")
        self.current = z
        self._publish_if_due(force=False)

    # ------------------------------------------------------------------ diagnostics
    def _basis_text(self) -> str:
        d, _ = self.density()
        if self.survey is not None and not self.survey.is_pile:
            return f"surveyed zones from {self.survey.path}"
        if self.survey is not None:
            alpha, toe_x = self.survey.alpha, self.survey.toe_x
            return f"surveyed slope {math.degrees(alpha):.1f} deg, toe {toe_x:.3f} m, {d:g} kg/m^3"
        alpha, toe_x = self.basis[:2]
        return f"slope {math.degrees(alpha):.1f} deg, toe {toe_x:.3f} m, {d:g} kg/m^3"

    def _report(self):
        now = time.monotonic()
        d, d_src = self.density()
        values = {"source": self.source, "density": d, "density_source": d_src, "received": self.received,
                  "rejected": self.rejected, "published": self.published,
                  "republish_threshold": self.republisher.threshold}
        pub = self.republisher.published
        if pub is not None:
            values.update(asdict(pub))
            if self.current is not None:
                values["pending_change_m"] = largest_change(self.current, pub)
        if self.survey is not None:
            values["surveyed_file"] = self.survey.path
            if self.survey.is_pile:
                values.update(slope_deg=math.degrees(self.survey.alpha), toe_x=self.survey.toe_x)
        elif self.basis is not None:
            alpha, toe_x, residual, stamp = self.basis
            values.update(slope_deg=math.degrees(alpha), toe_x=toe_x, residual_m=residual, slope_stamp=stamp)
        if self.last_input is not None:
            values["input_age_s"] = now - self.last_input
        if self.problem is not None:
            kept = "; the last good zones stay latched" if pub is not None else "; no zones published yet"
            return ERROR, self.problem + kept, values
        if pub is None:
            return WARN, f"no slope yet on {self.topic}: no zones published", values
        msg = (f"end zone x {pub.x_min:.3f}-{pub.x_max:.3f} m, z > {pub.z_min:g} m, cutoff {pub.x_cutoff:.3f} m "
               f"({self._basis_text()})")
        if self.survey is None and now - self.last_input > self.p["stale_warn_s"]:
            return WARN, (f"no slope for {now - self.last_input:.1f} s on {self.topic} (the latched {msg} "
                          f"keeps its meaning)"), values
        return OK, msg, values


def main(args=None) -> int:
    return run_node(EndZoneNode, "end_zone_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
