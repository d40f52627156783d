"""`ros2 run lhd_loading_ros lidar_slope_node`: the muck pile's slope alpha from a LiDAR
above the pile (paper: real environment).

In:  sensor_msgs/LaserScan (a vertical scan plane over the pile) and/or sensor_msgs/PointCloud2.
Out: /lhd/pile/slope (std_msgs/Float64, rad), /lhd/pile/toe (geometry_msgs/PointStamped, where
     the face meets the floor, pile frame), /lhd/pile/fit_residual (std_msgs/Float64, m RMS).

The sensor's pose in the pile frame comes from parameters. Floor points are dropped, the face
is found by RANSAC among lines of plausible slope (the floor and the back wall cannot win) and
refined by least squares. Too few points: a warning and no publication.
"""
from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import LaserScan, PointCloud2
from std_msgs.msg import Float64

from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.perception.geometry import apply, transform
from lhd_loading_ros.perception.slope import TooFewPoints, cloud_to_points, fit_slope, scan_to_points

OUT_QOS = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)


class LidarSlopeNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lidar_slope_node", **node_kwargs)
        dp = self.declare_parameter
        dp("sensor_xyz", [0.6, 0.0, 1.6])
        dp("sensor_rpy", [math.pi / 2, 0.0, 0.0])
        dp("floor_z", 0.03)
        dp("min_points", 30)
        dp("ransac_iterations", 200)
        dp("inlier_threshold", 0.02)
        dp("slope_min_deg", 5.0)
        dp("slope_max_deg", 50.0)
        dp("frame_id", "pile")
        dp("scan_topic", "/lidar/scan")
        dp("cloud_topic", "/lidar/points")
        dp("seed", 0)
        g = lambda n: self.get_parameter(n).value  # noqa: E731
        xyz, rpy = list(g("sensor_xyz")), list(g("sensor_rpy"))
        if len(xyz) != 3 or len(rpy) != 3:
            raise ValueError(f"parameters 'sensor_xyz' and 'sensor_rpy' must hold 3 numbers each, got {xyz}, {rpy}")
        if not 0 < g("slope_min_deg") < g("slope_max_deg") < 90:
            raise ValueError("parameters must satisfy 0 < slope_min_deg < slope_max_deg < 90")
        self.T = transform(xyz, rpy)
        self.fit_kw = dict(floor_z=float(g("floor_z")), min_points=int(g("min_points")),
                           iterations=int(g("ransac_iterations")), threshold=float(g("inlier_threshold")),
                           slope_min=math.radians(g("slope_min_deg")), slope_max=math.radians(g("slope_max_deg")))
        self.rng = np.random.default_rng(int(g("seed")))
        self.frame_id = g("frame_id")
        self.pub_slope = self.create_publisher(Float64, "/lhd/pile/slope", OUT_QOS)
        self.pub_toe = self.create_publisher(PointStamped, "/lhd/pile/toe", OUT_QOS)
        self.pub_res = self.create_publisher(Float64, "/lhd/pile/fit_residual", OUT_QOS)
        self.create_subscription(LaserScan, g("scan_topic"), self._on_scan, qos_profile_sensor_data)
        self.create_subscription(PointCloud2, g("cloud_topic"), self._on_cloud, qos_profile_sensor_data)

    def _on_scan(self, msg: LaserScan) -> None:
        pts = scan_to_points(msg.angle_min, msg.angle_increment, msg.ranges, msg.range_min, msg.range_max)
        self._fit(pts, msg.header.stamp)

    def _on_cloud(self, msg: PointCloud2) -> None:
        try:
            pts = cloud_to_points(msg.fields, msg.point_step, msg.row_step, msg.width, msg.height, bytes(msg.data),
                                  msg.is_bigendian)
        except ValueError as exc:
            self.get_logger().error(f"bad PointCloud2: {exc}", throttle_duration_sec=5.0)
            return
        self._fit(pts, msg.header.stamp)

    def _fit(self, pts_sensor: np.ndarray, stamp) -> None:
        try:
            f = fit_slope(apply(self.T, pts_sensor), self.rng, **self.fit_kw)
        except TooFewPoints as exc:
            self.get_logger().warn(f"no slope estimate: {exc}", throttle_duration_sec=2.0)
            return
        self.pub_slope.publish(Float64(data=f.alpha))
        toe = PointStamped()
        toe.header.stamp = stamp
        toe.header.frame_id = self.frame_id
        toe.point.x = f.toe_x
        self.pub_toe.publish(toe)
        self.pub_res.publish(Float64(data=f.residual))


def main(args=None) -> int:
    return run_node(LidarSlopeNode, "lidar_slope_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
