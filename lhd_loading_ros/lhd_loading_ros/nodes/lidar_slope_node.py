"""`ros2 run lhd_loading_ros lidar_slope_node`: the muck pile's slope alpha from a LiDAR
above the pile (paper: real environment).

In:  sensor_msgs/LaserScan (a vertical scan plane over the pile) and/or sensor_msgs/PointCloud2.
Out (under /lhd, or the node's namespace), all reliable + transient local, keep-last 1
(latched: the slope changes once per attempt and a late policy node still gets it):
  pile/slope          std_msgs/Float64            alpha, rad (the topic contract; no stamp)
  pile/slope_stamped  geometry_msgs/Vector3Stamped the same fit with the scan's stamp:
                                                   x = alpha (rad), y = toe x (m), z = RMS residual (m)
  pile/toe            geometry_msgs/PointStamped   where the face meets the floor, pile frame
  pile/fit_residual   std_msgs/Float64             m RMS
and /diagnostics.

The sensor's pose in the pile frame comes from parameters. The face is fitted robustly
(perception/slope.py: only points between floor and `max_z` and near the scan plane; the face
must rise from the floor; then the whole face at its own roughness). What is published is the
median of the latest `filter_window` fits up to `filter_max_age` old (perception/slope.SlopeFilter:
a pile does not move between scans; one scan that disagrees by more than new_pile_slope_deg /
new_pile_toe_m is held out and publishes nothing, `new_pile_scans` in a row that agree with each
other are a new pile). Ages are by arrival here, not by stamp (a bag replayed at another speed
changes which scans the median spans); after a pause longer than filter_max_age the first scan
stands alone. A scan without a face, or with a face outside [slope_min_deg, slope_max_deg],
publishes nothing and says why in /diagnostics and a throttled log (per kind of problem), and so
does a scan whose header cannot place its beams (perception/slope.scan_problem: angle_max must be
angle_min + (n - 1) angle_increment within one increment; 0 <= range_min < range_max; intensities
empty or one per range), whose ranges
all lie outside [range_min, range_max], or whose stamp is zero or ahead of this node's clock
(ros/stamps.py). Every output carries the stamp
of the newest scan that agrees with it, so the last value never looks fresher than the scans behind
it (consumers judge age by stamp).
"""
from __future__ import annotations

import math
import time

import numpy as np
from geometry_msgs.msg import PointStamped, Vector3Stamped
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan, PointCloud2
from std_msgs.msg import Float64

from lhd_loading_ros.perception.geometry import apply, transform
from lhd_loading_ros.perception.slope import (NoSlope, SlopeFilter, SlopeOutOfRange, cloud_to_points, fit_slope,
                                              scan_problem, scan_to_points)
from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, topic_prefix
from lhd_loading_ros.ros.qos import LATCHED_QOS
from lhd_loading_ros.ros.stamps import KindThrottle, stamp_problem
from lhd_loading_ros.ros.run import run_node

NO_SCAN_WARN_S = 5.0     # diagnostics: WARN when no scan came for this long
HELD_WARN_SCANS = 3      # diagnostics: WARN when this many scans in a row were held out by the filter


class LidarSlopeNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lidar_slope_node", **node_kwargs)
        self.p = Params(self, [
            Param("sensor_xyz", [0.6, 0.0, 1.6], "LiDAR position in the pile frame (m)", length=3),
            Param("sensor_rpy", [math.pi / 2, 0.0, 0.0], "LiDAR roll, pitch, yaw in the pile frame (rad)", length=3),
            Param("floor_z", 0.03, "points at or below this height (m) are floor", lo=-0.5, hi=0.5),
            Param("max_z", 1.5, "points at or above this height (m) are ignored: ceiling, brow, drawbell; "
                  "must be above the pile's crest", lo=0.1, hi=20.0),
            Param("max_abs_y", 0.3, "points farther than this (m) from the pile's XZ plane are ignored "
                  "(drift side walls in a 3-D cloud)", lo=0.01, hi=20.0),
            Param("min_points", 30, "points on the face needed for a slope", lo=3, hi=100000),
            Param("ransac_iterations", 200, "RANSAC line proposals per scan", lo=10, hi=100000,
                  on_change=lambda v: self._set_fit(iterations=v)),
            Param("inlier_threshold", 0.02, "RANSAC inlier band (m), about twice the range noise", lo=0.001, hi=0.5,
                  on_change=lambda v: self._set_fit(threshold=v)),
            Param("slope_min_deg", 5.0, "smallest physical pile slope published (deg)", lo=0.5, hi=89.0,
                  check=lambda v: self._range_problem(v, None),
                  on_change=lambda v: self._set_fit(slope_min=math.radians(v))),
            Param("slope_max_deg", 50.0, "largest physical pile slope published (deg)", lo=0.5, hi=89.0,
                  check=lambda v: self._range_problem(None, v),
                  on_change=lambda v: self._set_fit(slope_max=math.radians(v))),
            Param("frame_id", "pile", "frame of the toe point"),
            Param("sensor_frame_id", "lidar", "the frame the scans and clouds must be in: the one sensor_xyz / "
                  "sensor_rpy describe (another sensor's scans fitted with this mount give a wrong slope); "
                  "'' takes any frame"),
            Param("scan_topic", "/lidar/scan", "LaserScan input (sensor-data QoS)"),
            Param("cloud_topic", "/lidar/points", "PointCloud2 input (sensor-data QoS)"),
            Param("seed", 0, "RANSAC random seed", lo=0, hi=2**31 - 1),
            Param("filter_window", 5, "the slope published is the median of this many latest fits (1: every "
                  "scan's own fit)", lo=1, hi=1000),
            Param("filter_max_age", 2.0, "s: fits older than this leave the median", lo=0.01, hi=3600.0),
            Param("new_pile_slope_deg", 3.0, "deg: a fit this far from the median in slope is held out, "
                  "unless new_pile_scans in a row agree (a new pile)", lo=0.01, hi=90.0),
            Param("new_pile_toe_m", 0.10, "m: the same for the toe", lo=0.001, hi=100.0),
            Param("new_pile_scans", 2, "scans in a row that agree with each other and not with the median: "
                  "a new pile", lo=1, hi=100),
            Param("namespace_prefix", "/lhd", "topic prefix when the node runs in the root namespace"),
        ])
        p = self.p
        self.T = transform(p["sensor_xyz"], p["sensor_rpy"])
        self.fit_kw = dict(floor_z=p["floor_z"], max_z=p["max_z"], max_abs_y=p["max_abs_y"],
                           min_points=p["min_points"], iterations=p["ransac_iterations"],
                           threshold=p["inlier_threshold"], slope_min=math.radians(p["slope_min_deg"]),
                           slope_max=math.radians(p["slope_max_deg"]))
        self.rng = np.random.default_rng(p["seed"])
        self.filter = SlopeFilter(p["filter_window"], p["filter_max_age"], p["new_pile_slope_deg"],
                                  p["new_pile_toe_m"], p["new_pile_scans"])
        self.frame_id = p["frame_id"]
        self.sensor_frame_id = p["sensor_frame_id"]
        ns = topic_prefix(self, p["namespace_prefix"])
        self.pub_slope = self.create_publisher(Float64, f"{ns}/pile/slope", LATCHED_QOS)
        self.pub_stamped = self.create_publisher(Vector3Stamped, f"{ns}/pile/slope_stamped", LATCHED_QOS)
        self.pub_toe = self.create_publisher(PointStamped, f"{ns}/pile/toe", LATCHED_QOS)
        self.pub_res = self.create_publisher(Float64, f"{ns}/pile/fit_residual", LATCHED_QOS)
        self.create_subscription(LaserScan, p["scan_topic"], self._on_scan, qos_profile_sensor_data)
        self.create_subscription(PointCloud2, p["cloud_topic"], self._on_cloud, qos_profile_sensor_data)
        self.last_scan: float | None = None     # monotonic arrival of the last scan or cloud
        self.last_fit = None                    # (SlopeFit, monotonic time)
        self.problem: str | None = None         # why the last scan gave no slope
        self.scans = self.fits = 0
        self.held_in_a_row = 0                  # scans held out by the filter since the last publication
        self.last_stamp_ns: int | None = None   # stamp of the last scan fitted
        self.log_throttle = KindThrottle(2.0)
        self.diag = Diagnostics(self, {"slope": self._report})

    def _range_problem(self, lo_deg, hi_deg) -> str | None:
        """slope_min_deg < slope_max_deg, checked against the other's current value."""
        other = "slope_max_deg" if hi_deg is None else "slope_min_deg"
        if not self.has_parameter(other):
            return None     # declared next; checked then
        v = self.get_parameter(other).value
        lo, hi = (lo_deg, v) if hi_deg is None else (v, hi_deg)
        return None if lo < hi else f"needs slope_min_deg < slope_max_deg (got {lo:g} and {hi:g})"

    def _set_fit(self, **kw) -> None:
        self.fit_kw.update(kw)

    def _frame_problem(self, frame: str, what: str) -> str | None:
        """A scan or cloud from another frame than the mount this node knows (a review, 2026-11-30: the
        horizontal LiDAR's scans of a 20 deg pile were fitted with this mount as a 30 deg one, said OK)."""
        if self.sensor_frame_id and frame != self.sensor_frame_id:
            return (f"{what} in frame {frame!r}; expected {self.sensor_frame_id!r} (sensor_frame_id: the frame "
                    "sensor_xyz / sensor_rpy describe; set it to this LiDAR's frame, or '' to take any)")
        return None

    def _on_scan(self, msg: LaserScan) -> None:
        wrong = self._frame_problem(msg.header.frame_id, "scan")
        if wrong is not None:
            self._refused(wrong)
            return
        n = len(msg.ranges)
        bad = scan_problem(msg.angle_min, msg.angle_max, msg.angle_increment, n, msg.range_min, msg.range_max,
                           len(msg.intensities))
        if bad is not None:
            self._refused(bad)
            return
        pts = scan_to_points(msg.angle_min, msg.angle_increment, msg.ranges, msg.range_min, msg.range_max)
        if len(pts) == 0:
            r = np.asarray(msg.ranges, dtype=np.float64)
            finite = int(np.isfinite(r).sum())
            self._refused(f"no range of the scan's {n} beams lies in [range_min {msg.range_min:g}, range_max "
                          f"{msg.range_max:g}] m ({n - finite} inf or NaN, {finite} outside): expected ranges in "
                          "metres (nothing in view, or a driver reporting another unit?)")
            return
        self._fit(pts, msg.header.stamp)

    def _on_cloud(self, msg: PointCloud2) -> None:
        wrong = self._frame_problem(msg.header.frame_id, "point cloud")
        if wrong is not None:
            self._refused(wrong)
            return
        try:
            pts = cloud_to_points(msg.fields, msg.point_step, msg.row_step, msg.width, msg.height, bytes(msg.data),
                                  msg.is_bigendian)
        except ValueError as exc:
            self._no_slope(f"bad PointCloud2: {exc}")
            return
        self._fit(pts, msg.header.stamp)

    def _refused(self, why: str) -> None:
        """A message that is not a measurement: counted as a scan, nothing published, said why."""
        self.last_scan = time.monotonic()
        self.scans += 1
        self._no_slope(why)

    def _fit(self, pts_sensor: np.ndarray, stamp) -> None:
        bad = stamp_problem(stamp.sec, stamp.nanosec, self.get_clock().now().nanoseconds, "scan")
        if bad is not None:
            self._refused(bad)
            return
        t_ns = stamp.sec * 1_000_000_000 + stamp.nanosec
        if self.last_stamp_ns is not None and t_ns < self.last_stamp_ns:
            self._warn(f"scan stamp went back from {self.last_stamp_ns / 1e9:.3f} to {t_ns / 1e9:.3f} s (a bag loop or "
                       "a driver restart): its slope carries the older stamp")
        self.last_stamp_ns = t_ns
        self.last_scan = time.monotonic()
        self.scans += 1
        try:
            f = fit_slope(apply(self.T, pts_sensor), self.rng, **self.fit_kw)
        except SlopeOutOfRange as exc:
            self._no_slope(str(exc))
            return
        except NoSlope as exc:
            self._no_slope(f"no pile in scan: {exc}")
            return
        except Exception as exc:        # a scan no test foresaw must not end the node: nothing published, said why
            self._no_slope(f"slope fit failed on this scan ({type(exc).__name__}: {exc}); please report it with a "
                           f"recording of the scan")
            return
        if not all(math.isfinite(v) for v in (f.alpha, f.toe_x, f.residual)):
            self._no_slope("fit not finite")
            return
        fit_alpha, fit_toe = f.alpha, f.toe_x
        self.problem = None
        self.fits += 1
        f = self.filter.add(self.last_scan, f)
        if f is None:
            self.held_in_a_row += 1
            self.get_logger().info(f"scan held out: its slope {math.degrees(fit_alpha):.1f} deg / toe {fit_toe:.3f} m "
                                   f"disagrees with the median of the latest scans; published when "
                                   f"{self.p['new_pile_scans']} scans in a row agree (a new pile)",
                                   throttle_duration_sec=2.0)
            return
        self.held_in_a_row = 0
        self.last_fit = (f, self.last_scan)
        self.pub_slope.publish(Float64(data=f.alpha))
        vs = Vector3Stamped()
        vs.header.stamp, vs.header.frame_id = stamp, self.frame_id
        vs.vector.x, vs.vector.y, vs.vector.z = f.alpha, f.toe_x, f.residual
        self.pub_stamped.publish(vs)
        toe = PointStamped()
        toe.header.stamp, toe.header.frame_id = stamp, self.frame_id
        toe.point.x = f.toe_x
        self.pub_toe.publish(toe)
        self.pub_res.publish(Float64(data=f.residual))

    def _no_slope(self, why: str) -> None:
        self.problem = why
        self._warn(f"no slope published: {why}")

    def _warn(self, msg: str) -> None:
        if self.log_throttle.due(msg):      # throttled per kind of problem: one does not hide another
            self.get_logger().warn(msg)

    def _report(self):
        now = time.monotonic()
        values = {"scans": self.scans, "fits": self.fits, "held_out": self.filter.held_out,
                  "fits_in_median": len(self.filter.fits)}
        if self.last_fit is not None:
            f, t = self.last_fit
            values.update(slope_deg=math.degrees(f.alpha), toe_x=f.toe_x, residual_m=f.residual, fit_age_s=now - t)
        if self.last_scan is None:
            return WARN, "no scan yet", values
        if now - self.last_scan > NO_SCAN_WARN_S:
            return WARN, f"no scan for {now - self.last_scan:.1f} s", values
        if self.problem is not None:
            return ERROR, self.problem, values
        if self.held_in_a_row >= HELD_WARN_SCANS:
            return WARN, (f"{self.held_in_a_row} scans in a row held out: they disagree with the published slope "
                          f"{math.degrees(self.last_fit[0].alpha):.1f} deg and with each other (a changing or rough "
                          f"pile); the slope keeps its older stamp"), values
        return OK, f"slope {math.degrees(self.last_fit[0].alpha):.1f} deg", values


def main(args=None) -> int:
    return run_node(LidarSlopeNode, "lidar_slope_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
