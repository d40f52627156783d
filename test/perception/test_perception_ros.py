"""ArUco pose node and LiDAR slope node as real processes over DDS, fed by a test node."""
import math
import time

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PointStamped, PoseStamped
from nav_msgs.msg import Odometry
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image, LaserScan, PointCloud2, PointField
from std_msgs.msg import Bool, Float64

from lhd_loading_ros.perception.geometry import transform
from lhd_loading_ros.perception.synthetic import (CAMERA_RPY, drive_poses, intrinsics, marker_texture, render,
                                                  synthetic_scan)

from rosutil import RosProcess, init_ros, shutdown_ros, spin_until


@pytest.fixture(scope="module")
def ros():
    init_ros()
    yield
    shutdown_ros()


def image_msg(gray, t, encoding="mono8"):
    m = Image()
    m.header.stamp.sec, m.header.stamp.nanosec = int(t), int((t % 1) * 1e9)
    m.header.frame_id = "camera"
    m.height, m.width = gray.shape
    if encoding == "bgr8":
        gray = np.dstack([gray, gray, gray])
    m.encoding = encoding
    m.step = gray.shape[1] * (3 if encoding == "bgr8" else 1)
    m.data = gray.tobytes()
    return m


def test_aruco_node_pose_speed_loss_and_staleness(ros, tmp_path):
    # reliable images: best-effort 300 kB frames lose fragments on this machine's loopback, which
    # would test the transport rather than the node (the default stays sensor-data QoS)
    proc = RosProcess("lhd_loading_ros.nodes.aruco_pose_node", {"stale_timeout": 0.5, "image_reliable": True},
                      tmp_path / "aruco.log")
    node = rclpy.create_node("aruco_test")
    odom, poses, stale = [], [], []
    node.create_subscription(Odometry, "/lhd/odom", odom.append, 50)
    node.create_subscription(PoseStamped, "/lhd/aruco/marker_pose", poses.append, 50)
    node.create_subscription(Bool, "/lhd/aruco/stale", lambda m: stale.append(m.data), 50)
    pub_img = node.create_publisher(Image, "/camera/image_raw", 10)
    pub_info = node.create_publisher(CameraInfo, "/camera/camera_info", qos_profile_sensor_data)
    rng = np.random.default_rng(0)
    K = intrinsics(640, 480)
    T_pc = transform((-0.5, 0.0, 1.5), CAMERA_RPY)
    tex = marker_texture("DICT_4X4_50", 7)
    fps, speed, t0 = 30.0, 0.37, 100.0
    ts = np.arange(45) / fps
    truth = drive_poses(ts, -0.75, speed)
    frames = [render(K, 640, 480, np.linalg.inv(T_pc) @ T, tex, 0.12, rng) for T in truth]
    try:
        assert spin_until(node, lambda: pub_img.get_subscription_count() > 0, 20.0), proc.log()   # matched from this side
        spin_until(node, lambda: False, 0.5)
        # frames before any CameraInfo are ignored
        for k in range(5):
            pub_img.publish(image_msg(frames[k], t0 + ts[k]))
            spin_until(node, lambda: False, 1 / fps)
        assert not odom
        info = CameraInfo()
        info.width, info.height, info.k = 640, 480, K.ravel().tolist()
        info.d = [0.0] * 5
        for _ in range(3):
            pub_info.publish(info)
            spin_until(node, lambda: False, 0.05)
        for k in range(len(frames)):
            pub_img.publish(image_msg(frames[k], t0 + ts[k], "bgr8" if k % 2 else "mono8"))
            spin_until(node, lambda: False, 1 / fps)
        assert spin_until(node, lambda: len(odom) >= 40, 5.0), (len(odom), proc.log())
        # the node may still be working through its image queue (a loaded machine): wait until the
        # last frame's odometry came, so that the counts below are the final ones
        last_ns = int(round((t0 + ts[-1]) * 1e9))
        spin_until(node, lambda: odom and odom[-1].header.stamp.sec * 10**9 + odom[-1].header.stamp.nanosec
                   >= last_ns - 1000, 5.0)
        spin_until(node, lambda: False, 0.3)
        T_mb = transform((0.10, 0.0, -0.213), (0, 0, 0))
        for o in odom:
            t = o.header.stamp.sec + o.header.stamp.nanosec * 1e-9 - t0
            k = int(round(t * fps))
            true_base = (truth[k] @ T_mb)[:3, 3]
            p = o.pose.pose.position
            assert np.linalg.norm([p.x - true_base[0], p.y - true_base[1], p.z - true_base[2]]) < 0.01
            assert o.header.frame_id == "pile" and o.child_frame_id == "base_link"
        speeds = [o.twist.twist.linear.x for o in odom]
        assert all(math.isfinite(v) for v in speeds)
        assert all(o.twist.covariance[0] == pytest.approx(0.025 ** 2) for o in odom)   # the Kalman filter's measured error
        # the axes it does not measure say so (not 0, which a fuser reads as perfect knowledge)
        assert all([o.twist.covariance[7 * i] for i in range(1, 6)] == [1.0e6] * 5 for o in odom)
        assert len(speeds) > 30 and max(abs(v - speed) for v in speeds) < 0.02
        assert poses and not stale[-1]
        # the marker leaves the view: no odometry (an unknown speed is no message, never NaN),
        # no pose, and after stale_timeout the estimate is stale
        n, npose = len(odom), len(poses)
        blank = render(K, 640, 480, np.linalg.inv(T_pc) @ transform((5.0, 0, 0.35), (0, 0, 0)), tex, 0.12, rng)
        for k in range(6):
            pub_img.publish(image_msg(blank, t0 + 2.0 + k / fps))
            spin_until(node, lambda: False, 1 / fps)
        spin_until(node, lambda: False, 0.5)
        assert len(odom) == n and len(poses) == npose
        assert spin_until(node, lambda: stale and stale[-1], 3.0)
        m = len(odom)
        pub_img.publish(image_msg(blank, t0 + 3.0))
        spin_until(node, lambda: False, 0.3)
        assert len(odom) == m
    finally:
        node.destroy_node()
        assert proc.stop() == 0, proc.log()


def test_aruco_node_rejects_unknown_encodings_clearly(ros, tmp_path):
    proc = RosProcess("lhd_loading_ros.nodes.aruco_pose_node", {}, tmp_path / "aruco.log")
    node = rclpy.create_node("aruco_enc_test")
    pub_img = node.create_publisher(Image, "/camera/image_raw", qos_profile_sensor_data)
    pub_info = node.create_publisher(CameraInfo, "/camera/camera_info", qos_profile_sensor_data)
    try:
        assert spin_until(node, lambda: node.count_subscribers("/camera/image_raw") > 0, 20.0), proc.log()
        info = CameraInfo()
        info.k = intrinsics(64, 48).ravel().tolist()
        info.width, info.height = 64, 48
        m = Image()
        m.header.stamp.sec = 100
        m.height, m.width, m.encoding, m.step = 48, 64, "16UC1", 128
        m.data = bytes(48 * 128)
        t_end = time.monotonic() + 3.0
        while time.monotonic() < t_end and "unsupported image encoding" not in proc.log():
            pub_info.publish(info)
            pub_img.publish(m)
            spin_until(node, lambda: False, 0.1)
        assert "unsupported image encoding '16UC1'; expected one of mono8, bgr8, rgb8" in proc.log()
        assert proc.alive()
    finally:
        node.destroy_node()
        assert proc.stop() == 0


def now_stamp(m):
    """The acquisition time a driver gives (the node refuses a zero stamp)."""
    t = time.time()
    m.header.stamp.sec, m.header.stamp.nanosec = int(t), int((t % 1) * 1e9)


def scan_msg(ranges, amin, inc):
    m = LaserScan()
    m.header.frame_id = "lidar"
    now_stamp(m)
    m.angle_min, m.angle_increment = float(amin), float(inc)
    m.angle_max = float(amin + inc * (len(ranges) - 1))
    m.range_min, m.range_max = 0.05, 30.0
    m.ranges = [float(r) for r in ranges]
    return m


def cloud_msg(pts):
    m = PointCloud2()
    m.header.frame_id = "lidar"
    now_stamp(m)
    m.height, m.width = 1, len(pts)
    m.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, n in enumerate("xyz")]
    m.fields.append(PointField(name="intensity", offset=12, datatype=PointField.FLOAT32, count=1))
    m.is_bigendian, m.point_step = False, 16
    m.row_step = 16 * len(pts)
    arr = np.zeros((len(pts), 4), np.float32)
    arr[:, :3] = pts
    m.data = arr.tobytes()
    m.is_dense = True
    return m


def test_lidar_node_slope_from_scans_and_clouds(ros, tmp_path):
    # each scan's own fit (filter_window 1): piles of 15, 30 and 22 deg one scan after the other
    proc = RosProcess("lhd_loading_ros.nodes.lidar_slope_node", {"filter_window": 1}, tmp_path / "lidar.log")
    node = rclpy.create_node("lidar_test")
    slopes, toes, res = [], [], []
    node.create_subscription(Float64, "/lhd/pile/slope", lambda m: slopes.append(m.data), 20)
    node.create_subscription(PointStamped, "/lhd/pile/toe", toes.append, 20)
    node.create_subscription(Float64, "/lhd/pile/fit_residual", lambda m: res.append(m.data), 20)
    pub_scan = node.create_publisher(LaserScan, "/lidar/scan", qos_profile_sensor_data)
    pub_cloud = node.create_publisher(PointCloud2, "/lidar/points", qos_profile_sensor_data)
    rng = np.random.default_rng(4)
    try:
        assert spin_until(node, lambda: pub_scan.get_subscription_count() > 0, 20.0), proc.log()   # matched from this side
        spin_until(node, lambda: False, 0.5)
        for alpha in (15.0, 30.0):
            r, amin, inc, rpy = synthetic_scan(math.radians(alpha), rng)
            n, nt, nr = len(slopes), len(toes), len(res)
            pub_scan.publish(scan_msg(r, amin, inc))
            assert spin_until(node, lambda: len(slopes) > n and len(toes) > nt and len(res) > nr, 5.0), proc.log()
            assert abs(math.degrees(slopes[-1]) - alpha) < 1.0
            assert abs(toes[-1].point.x) < 0.03 and toes[-1].header.frame_id == "pile" and res[-1] < 0.015
        # a point cloud: the same scan plane swept across y, in the scanner's frame
        r, amin, inc, rpy = synthetic_scan(math.radians(22.0), rng)
        from lhd_loading_ros.perception.slope import scan_to_points
        p = scan_to_points(amin, inc, r, 0.05, 30.0)
        cloud = np.concatenate([p + [0.0, 0.0, dy] for dy in (-0.1, 0.0, 0.1)])  # scanner z = pile -y
        n = len(slopes)
        pub_cloud.publish(cloud_msg(cloud))
        assert spin_until(node, lambda: len(slopes) > n, 5.0), proc.log()
        assert abs(math.degrees(slopes[-1]) - 22.0) < 1.0
        # too few points: a warning, no publication
        n = len(slopes)
        pub_scan.publish(scan_msg([float("inf")] * 700 + [1.0] * 5, amin, inc))
        spin_until(node, lambda: False, 1.0)
        assert len(slopes) == n
        assert spin_until(node, lambda: "no slope published: no pile in scan" in proc.log(), 3.0)
    finally:
        node.destroy_node()
        assert proc.stop() == 0, proc.log()
