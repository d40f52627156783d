"""`ros2 run lhd_loading_ros aruco_pose_node`: machine pose and forward speed v_x from an
ArUco marker on the LHD seen by a camera above the draw point (paper: real environment).

In:  sensor_msgs/Image (mono8, bgr8, rgb8, bgra8, rgba8) and sensor_msgs/CameraInfo.
Out: the marker pose (geometry_msgs/PoseStamped, pile frame), /lhd/odom (nav_msgs/Odometry:
     base_link pose in the pile frame, twist.linear.x = v_x), /lhd/aruco/stale (std_msgs/Bool).

Frames before the first CameraInfo are ignored. A frame without the marker holds the last
pose with a covariance that grows with the time since the marker was last seen, and reports
no speed (twist.linear.x = NaN, covariance -1: unknown) -- never an invented one. After
`stale_timeout` without the marker (or without images) /lhd/aruco/stale turns true and
odometry stops, so consumers' input timeouts take over.
"""
from __future__ import annotations

import math
import time

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Bool

from lhd_loading_ros.perception.aruco import CameraModel, ImageEncodingError, MarkerDetector, VelocityEstimator, image_to_gray, level
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.perception.geometry import quaternion_xyzw, transform

# Camera streams are sensor data (best effort matches any publisher; late frames are useless).
# Our outputs are consumed by the policy and the bridge: reliable, keep-last 5.
OUT_QOS = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
POSE_VAR = 0.005 ** 2     # m^2, position variance of a fresh detection (about 5 mm, see docs/perception.md)
SPEED_VAR = 0.01 ** 2     # (m/s)^2


def _vec3(node: Node, name: str) -> list[float]:
    v = list(node.get_parameter(name).value)
    if len(v) != 3 or not all(math.isfinite(float(x)) for x in v):
        raise ValueError(f"parameter '{name}' must be 3 finite numbers, got {v}")
    return [float(x) for x in v]


class ArucoPoseNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("aruco_pose_node", **node_kwargs)
        dp = self.declare_parameter
        dp("dictionary", "DICT_4X4_50")
        dp("marker_id", 7)
        dp("marker_size", 0.12)
        dp("camera_xyz", [-0.5, 0.0, 1.5])
        dp("camera_rpy", [math.pi, 0.0, -math.pi / 2])
        dp("marker_to_base_xyz", [0.10, 0.0, -0.213])
        dp("marker_to_base_rpy", [0.0, 0.0, 0.0])
        dp("planar_motion", True)
        dp("velocity_window", 0.3)
        dp("stale_timeout", 0.5)
        dp("loss_variance_rate", 0.01)
        dp("frame_id", "pile")
        dp("child_frame_id", "base_link")
        dp("image_topic", "/camera/image_raw")
        dp("camera_info_topic", "/camera/camera_info")
        dp("pose_topic", "/lhd/aruco/marker_pose")
        dp("odom_topic", "/lhd/odom")
        dp("stale_topic", "/lhd/aruco/stale")
        dp("image_reliable", False)
        g = lambda n: self.get_parameter(n).value  # noqa: E731
        for n in ("velocity_window", "stale_timeout", "marker_size"):
            if not (isinstance(g(n), (int, float)) and g(n) > 0):
                raise ValueError(f"parameter '{n}' must be > 0, got {g(n)!r}")
        self.detector = MarkerDetector(g("dictionary"), g("marker_id"), g("marker_size"))
        self.T_pile_cam = transform(_vec3(self, "camera_xyz"), _vec3(self, "camera_rpy"))
        self.T_marker_base = transform(_vec3(self, "marker_to_base_xyz"), _vec3(self, "marker_to_base_rpy"))
        self.vel = VelocityEstimator(g("velocity_window"))
        self.stale_timeout = float(g("stale_timeout"))
        self.planar = bool(g("planar_motion"))
        self.loss_rate = float(g("loss_variance_rate"))
        self.frame_id, self.child_frame_id = g("frame_id"), g("child_frame_id")
        self.cam: CameraModel | None = None
        self.last_seen: float | None = None   # arrival time (monotonic) of the last detection
        self.last_base: np.ndarray | None = None
        self.last_marker: np.ndarray | None = None
        self.last_image: float | None = None
        self.stale = True
        self.frames = self.detections = 0
        self.pub_pose = self.create_publisher(PoseStamped, g("pose_topic"), OUT_QOS)
        self.pub_odom = self.create_publisher(Odometry, g("odom_topic"), OUT_QOS)
        self.pub_stale = self.create_publisher(Bool, g("stale_topic"), OUT_QOS)
        self.create_subscription(CameraInfo, g("camera_info_topic"), self._on_info, qos_profile_sensor_data)
        # sensor-data QoS by default (best effort: matches any camera driver, late frames are
        # worthless); image_reliable=true for lossless links such as recorded data or tests
        img_qos = (QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
                   if g("image_reliable") else qos_profile_sensor_data)
        self.create_subscription(Image, g("image_topic"), self._on_image, img_qos)
        self.create_timer(0.1, self._check_stale)

    def _on_info(self, msg: CameraInfo) -> None:
        try:
            self.cam = CameraModel.from_camera_info(msg.k, msg.d)
        except ValueError as exc:
            self.get_logger().warn(str(exc), throttle_duration_sec=5.0)

    def _on_image(self, msg: Image) -> None:
        now = time.monotonic()
        self.last_image = now
        if self.cam is None:
            self.get_logger().info("waiting for CameraInfo; image ignored", throttle_duration_sec=5.0)
            return
        try:
            gray = image_to_gray(msg.height, msg.width, msg.encoding, msg.step, bytes(msg.data))
        except ImageEncodingError as exc:
            self.get_logger().error(str(exc), throttle_duration_sec=5.0)
            return
        self.frames += 1
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        corners = self.detector.detect(gray)
        T_cam_marker = self.detector.pose(corners, self.cam) if corners is not None else None
        if T_cam_marker is None:
            self._publish_lost(msg, now)
            return
        self.detections += 1
        T_pile_marker = self.T_pile_cam @ T_cam_marker
        if self.planar:  # the machine drives on the floor: keep x, y, z and heading only
            T_pile_marker = level(T_pile_marker)
        T_base = T_pile_marker @ self.T_marker_base
        self.last_seen, self.last_base, self.last_marker = now, T_base, T_pile_marker
        # v_x from the marker's own position: the articulation is locked and the machine drives
        # straight, so every point of the rear frame moves with the same v_x, and the marker
        # origin is free of the lever-arm noise that orientation jitter puts on base_link.
        self.vel.add(t, float(T_pile_marker[0, 3]))
        self._set_stale(False)
        v = self.vel.velocity()
        self._publish(msg.header.stamp, T_pile_marker, T_base, v, POSE_VAR)

    def _publish_lost(self, msg: Image, now: float) -> None:
        if self.last_base is None or self.stale:
            return
        lost_for = now - self.last_seen
        if lost_for > self.stale_timeout:
            self._set_stale(True)
            return
        self.vel.reset()  # a speed needs fresh consecutive detections
        self._publish(msg.header.stamp, self.last_marker, self.last_base, None, POSE_VAR + self.loss_rate * lost_for)

    def _publish(self, stamp, T_marker, T_base, v, pose_var) -> None:
        ps = PoseStamped()
        ps.header.stamp = stamp
        ps.header.frame_id = self.frame_id
        _fill_pose(ps.pose, T_marker)
        self.pub_pose.publish(ps)
        od = Odometry()
        od.header.stamp = stamp
        od.header.frame_id = self.frame_id
        od.child_frame_id = self.child_frame_id
        _fill_pose(od.pose.pose, T_base)
        cov = [0.0] * 36
        for i in range(3):
            cov[7 * i] = pose_var
        for i in range(3, 6):
            cov[7 * i] = pose_var * 4.0  # rad^2: orientation from a 0.12 m marker is ~2x less certain
        od.pose.covariance = cov
        tc = [0.0] * 36
        if v is None:
            od.twist.twist.linear.x = float("nan")
            tc[0] = -1.0  # unknown: no speed is reported rather than an invented one
        else:
            od.twist.twist.linear.x = v
            tc[0] = SPEED_VAR
        od.twist.covariance = tc
        self.pub_odom.publish(od)

    def _set_stale(self, s: bool) -> None:
        if s != self.stale:
            self.stale = s
            if s:
                self.vel.reset()
                self.get_logger().warn("marker lost: odometry stale", throttle_duration_sec=2.0)
            self.pub_stale.publish(Bool(data=s))

    def _check_stale(self) -> None:
        """10 Hz: the marker (or the camera) gone for stale_timeout makes the estimate stale;
        the flag is republished every tick for late subscribers."""
        now = time.monotonic()
        seen = self.last_seen is not None and now - self.last_seen <= self.stale_timeout
        if not seen:
            self._set_stale(True)
        self.pub_stale.publish(Bool(data=self.stale))


def _fill_pose(pose, T) -> None:
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in T[:3, 3])
    q = quaternion_xyzw(T[:3, :3])
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q


def main(args=None) -> int:
    return run_node(ArucoPoseNode, "aruco_pose_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
