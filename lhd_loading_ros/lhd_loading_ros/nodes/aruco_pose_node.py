"""`ros2 run lhd_loading_ros aruco_pose_node`: machine pose and forward speed v_x from an
ArUco marker on the LHD seen by a camera above the draw point (paper: real environment).

In:  sensor_msgs/Image (mono8, bgr8, rgb8, bgra8, rgba8) and sensor_msgs/CameraInfo; optionally
     <prefix>/imu (sensor_msgs/Imu on the rear frame, axes = base_link's): with its orientation, a
     machine that tilts (its rear lifting as the boom pries at a buried bucket) is placed with its
     roll and pitch about the wheels on the floor, the odometry is that tilted pose (base_link raised
     and pitched: the bucket tip the controllers compute from it is the machine's) and v_x is
     base_link's (use_imu); with its linear
     acceleration too (in m/s^2 with gravity, REP 145: judged over each second), the speed filter
     integrates it between images (imu_acceleration;
     docs/perception.md "Camera and accelerometer").
Out (under /lhd, or the node's namespace):
  aruco/marker_pose  geometry_msgs/PoseStamped  every detection, pile frame, the image's stamp
  odom               nav_msgs/Odometry          base_link pose + twist.linear.x = v_x, ONLY when
                                                v_x is measured (see below)
  aruco/stale        std_msgs/Bool              true while the marker (or the camera) is gone
and /diagnostics (OK / WARN / ERROR with the reason).

"Unknown speed" is the absence of /lhd/odom, never a number: odometry is published only for
a detection whose v_x comes from consecutive detections (no lost or rejected frame between
them) with strictly increasing, non-zero image stamps. A lost marker, a rejected frame, a zero
or repeated stamp publish no odometry; a backward stamp restarts the speed estimate. v_x comes
from a constant-velocity Kalman filter on the marker's x (`velocity_filter: kalman`, the default:
the speed at the image's instant) or the least-squares slope over `velocity_window`
(`velocity_filter: window`: about half the window late); docs/perception.md compares them. Consumers
time out on /lhd/odom (the policy node: input timeout -> zero command; the bridge: odom_timeout)
and may read /lhd/aruco/stale and /diagnostics for the reason. Every published value is finite.
"""
from __future__ import annotations

import math
import time
from collections import deque

import cv2
import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image, Imu
from std_msgs.msg import Bool

from lhd_loading_ros.perception.aruco import (AmbiguousMarkerError, CameraModel, GravityCheck, ImageEncodingError,
                                              InertialVelocityEstimator, KalmanVelocityEstimator, MarkerDetector, MountingPrior, VelocityEstimator,
                                              dictionary, forward_acceleration, image_to_gray, level, marker_centre_ray,
                                              opencv_problem, position_on_plane, roll_pitch, tilted_base_position)
from lhd_loading_ros.perception.geometry import quaternion_xyzw, rpy_matrix, transform
from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import MEASUREMENT_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.ros.stamps import KindThrottle, stamp_problem
from lhd_loading_ros.task.imu_mount import level_force, level_orientation, zero_problem

POSE_VAR = 0.005 ** 2     # m^2, position variance of a fresh detection (about 5 mm, see docs/perception.md)
# (m/s)^2: the speed's error measured over simulated loading attempts (RMS against the simulator,
# docs/perception.md): the Kalman filter 0.025 m/s worst, the 0.3 s window 0.11 m/s (mostly its lag).
# Not the filter's own P: its random-walk model (q = 1 m^2/s^3) says 0.11 m/s, 4x the measured error.
SPEED_VAR = {"kalman": 0.025 ** 2, "window": 0.11 ** 2}
UNMEASURED_VAR = 1.0e6     # (m/s)^2, (rad/s)^2: a twist axis the node does not measure (the usual "ignore this" value)
# m: solvePnP's marker height may differ this much from marker_height before diagnostics warn (its
# own error is about 2 cm on the twin's images: 1.6 cm bias, 0.6 cm sd, docs/perception.md)
HEIGHT_TOLERANCE = 0.05


def _dictionary_problem(name: str) -> str | None:
    try:
        dictionary(name)
    except ValueError as exc:
        return str(exc)
    return None


class ArucoPoseNode(Node):
    def __init__(self, **node_kwargs):
        problem = opencv_problem()
        if problem:
            raise ValueError(problem)
        super().__init__("aruco_pose_node", **node_kwargs)
        self.p = p = Params(self, [
            Param("dictionary", "DICT_4X4_50", "ArUco dictionary (a cv2.aruco DICT_* name)", check=_dictionary_problem),
            Param("marker_id", 7, "id of the marker on the machine", lo=0, hi=4999),
            Param("marker_size", 0.12, "side of the marker's black square (m)", lo=0.001, hi=10.0),
            Param("camera_xyz", [-0.5, 0.0, 1.5], "camera optical frame position in the pile frame (m)", length=3),
            Param("camera_rpy", [math.pi, 0.0, -math.pi / 2], "camera optical frame roll, pitch, yaw (rad)", length=3),
            Param("marker_to_base_xyz", [0.10, 0.0, -0.213], "base_link position in the marker frame (m)", length=3),
            Param("marker_to_base_rpy", [0.0, 0.0, 0.0], "base_link roll, pitch, yaw in the marker frame (rad)",
                  length=3),
            Param("planar_motion", True, "keep position and heading only (the machine drives on a flat floor)"),
            Param("marker_height", 0.35, "planar_motion: height of the marker's centre above the floor (m; the "
                  "marker's position is where the camera ray through its centre meets that plane); 0: the "
                  "position solvePnP gives", lo=0.0, hi=100.0, on_change=self._set_marker_height),
            Param("velocity_filter", "kalman", "how v_x is estimated from x(t): kalman (constant-velocity Kalman "
                  "filter, no window lag) or window (least-squares slope over velocity_window)",
                  choices=("kalman", "window"), on_change=lambda v: self._set_filter(filter=v)),
            Param("velocity_accel_noise", 1.0, "kalman: spectral density of the machine's acceleration (m^2/s^3)",
                  lo=1e-4, hi=1e4, on_change=lambda v: self._set_filter(accel_noise=v)),
            Param("velocity_position_noise", 0.0005, "kalman: standard deviation of a detection's x (m)",
                  lo=1e-5, hi=0.1, on_change=lambda v: self._set_filter(position_noise=v)),
            Param("velocity_window", 0.3, "window: v_x is the least-squares slope of x(t) over this window (s)",
                  lo=0.02, hi=10.0, on_change=lambda v: self._set_filter(window=v)),
            Param("stale_timeout", 0.5, "without the marker or images this long (s): stale, odometry stops",
                  lo=0.02, hi=60.0, on_change=self._set_stale_timeout),
            Param("frame_id", "pile", "frame of the published poses"),
            Param("child_frame_id", "base_link", "child frame of the odometry"),
            Param("image_topic", "/camera/image_raw", "Image input"),
            Param("camera_info_topic", "/camera/camera_info", "CameraInfo input"),
            Param("image_reliable", False, "subscribe to images reliably (recordings, tests) instead of sensor-data QoS"),
            Param("match_info_frame", True, "refuse an image whose frame_id differs from its CameraInfo's (both set; "
                  "a leading / ignored): the calibration of another camera gives a wrong speed. false: where one "
                  "camera's image and CameraInfo are named differently"),
            Param("namespace_prefix", "/lhd", "topic prefix when the node runs in the root namespace"),
            Param("use_imu", True, "planar_motion: when <prefix>/imu (sensor_msgs/Imu on the rear frame) is fresh, "
                  "place base_link with its roll and pitch, the machine tilting about the wheels on the floor, "
                  "publish that tilted pose (base_link raised, pitched) and take v_x from base_link (without it: "
                  "the levelled pose, v_x from the marker)"),
            Param("imu_timeout", 0.2, "use_imu: an IMU sample older than this (s, from its stamp to the image's) "
                  "is not used (nor its acceleration held longer)", lo=0.001, hi=10.0, on_change=self._set_imu_timeout),
            Param("imu_window", 0.1, "use_imu: the roll and pitch at an image are the mean of the IMU samples of "
                  "this long a window ending at its stamp (s; white noise of the IMU would otherwise reach v_x "
                  "through the 0.5 m/rad lever of the tilt on x); 0: interpolated at the stamp",
                  lo=0.0, hi=2.0, on_change=lambda v: setattr(self, "imu_window", v)),
            Param("imu_zero_deg", [0.0, 0.0], "use_imu: [roll, pitch] deg the IMU reads with the machine standing on a "
                  "level floor (its mounting on the rear frame); taken off its orientation and acceleration. An IMU 2 deg "
                  "askew cost rld_machine every attempt in the twin (docs/real_machine.md Calibration step 9)", length=2,
                  check=zero_problem),
            Param("imu_deadband_deg", 0.3, "use_imu: a roll or pitch this small (deg) is the IMU's noise and "
                  "mounting error, not the machine's (a machine on its wheels on a flat floor stands level); larger "
                  "ones count beyond it (soft threshold: no step at the edge)", lo=0.0, hi=10.0,
                  on_change=lambda v: setattr(self, "imu_deadband", math.radians(v))),
            Param("imu_acceleration", True, "use_imu, velocity_filter kalman: when the IMU gives its linear "
                  "acceleration (linear_acceleration_covariance[0] != -1), the speed filter integrates it between "
                  "images and the images correct it (InertialVelocityEstimator; the IMU's axes are base_link's): "
                  "an abrupt stop at the pile is seen as it happens instead of 2-3 frames late"),
            Param("imu_accel_noise", 0.01, "imu_acceleration: spectral density of the integrated acceleration's "
                  "error (m^2/s^3: the sensor's noise and what the model leaves out)", lo=1e-6, hi=100.0,
                  on_change=lambda v: self._set_filter(imu_accel_noise=v)),
            Param("imu_accel_hold", 0.02, "imu_acceleration: how long past its stamp the newest acceleration sample "
                  "stands for the acceleration (s; one IMU period): an image whose instant the IMU has not covered yet "
                  "is predicted with it that far, beyond with the constant-velocity model; the late sample corrects the "
                  "next images", lo=0.0, hi=1.0, on_change=lambda v: self._set_filter(hold=v)),
            Param("imu_accel_wait", 0.025, "imu_acceleration: an image whose instant the live accelerometer has not "
                  "covered yet waits at most this long (s, wall time) for the sample that covers it before its v_x is "
                  "filtered and its odometry published (the pose is published at once); 0: never wait, the newest "
                  "sample is held (imu_accel_hold). Counted from the end of the image's detection; a node behind its "
                  "inputs first takes the IMU samples already queued, so a wait that finds none covering ends one "
                  "period later (at most twice this)",
                  lo=0.0, hi=0.5, on_change=self._set_imu_accel_wait),
            Param("wheelbase", 0.80, "use_imu: the front axle's distance ahead of base_link (the rear axle), m: "
                  "the pivot of a nose-down tilt", lo=0.01, hi=20.0),
        ])
        n_ids = dictionary(p["dictionary"]).bytesList.shape[0]
        if p["marker_id"] >= n_ids:
            raise ValueError(f"parameter 'marker_id' = {p['marker_id']} is invalid; {p['dictionary']} has ids 0..{n_ids - 1}")
        self.detector = MarkerDetector(p["dictionary"], p["marker_id"], p["marker_size"])
        self.T_pile_cam = transform(p["camera_xyz"], p["camera_rpy"])
        self.T_marker_base = transform(p["marker_to_base_xyz"], p["marker_to_base_rpy"])
        self.prior = MountingPrior(self.T_pile_cam, self.T_marker_base)
        self.imu_accel = bool(p["use_imu"] and p["imu_acceleration"])
        self._vel_params = {"filter": p["velocity_filter"], "accel_noise": p["velocity_accel_noise"],
                            "position_noise": p["velocity_position_noise"], "window": p["velocity_window"],
                            "max_gap": p["stale_timeout"], "imu_accel_noise": p["imu_accel_noise"],
                            "hold": p["imu_accel_hold"]}
        self.imu_timeout = p["imu_timeout"]
        self.vel = self._make_velocity()
        self.stale_timeout = p["stale_timeout"]
        self.planar = p["planar_motion"]
        self.marker_height = p["marker_height"]
        self.height_problem: str | None = None  # the marker seen far from marker_height
        self.frame_id, self.child_frame_id = p["frame_id"], p["child_frame_id"]
        self.use_imu, self.imu_timeout, self.wheelbase = p["use_imu"], p["imu_timeout"], p["wheelbase"]
        self.imu_zero = tuple(math.radians(float(v)) for v in p["imu_zero_deg"])
        self.match_info_frame = p["match_info_frame"]
        self.imu_window = p["imu_window"]
        self.imu_accel_wait = p["imu_accel_wait"]
        self.pending = None                     # (stamp, x, T_base) of an image waiting for the accelerometer
        self.imu_waits = self.imu_wait_timeouts = 0
        self._wait_timer = None                 # one-shot (steady clock) ending such a wait
        self._deadline_passed = False           # its first expiry came (queued IMU samples may still end it)
        self.imu_deadband = math.radians(p["imu_deadband_deg"])
        self.T_base_marker = np.linalg.inv(self.T_marker_base)          # the marker in base_link
        self.marker_in_base = self.T_base_marker[:3, 3]                  # the marker's centre in base_link
        self.imu: deque = deque(maxlen=32)      # (stamp s, roll, pitch) of recent IMU samples
        self.yaw = 0.0                          # the machine's heading from the last detection (rad)
        self.accel_samples = 0                  # IMU accelerations given to the speed filter
        self.imu_problem: str | None = None     # why the last IMU message was not used
        self.x_source = "marker"                # what v_x is estimated from: marker (levelled) or base_imu
        self.tilted = 0                         # detections placed with the IMU's tilt
        self._ray = None
        self.cam: CameraModel | None = None
        self.info_problem: str | None = None    # why the last CameraInfo was rejected
        self.image_problem: str | None = None   # why the last image was rejected
        self.stamp_problem: str | None = None   # why the last detection gave no speed
        self.info_frame_id = ""                 # the CameraInfo's frame_id (images of another frame are refused)
        self.camera_model_changes = 0           # CameraInfo changes that restarted the speed estimate
        self.imu_faults = 0                     # IMU messages not used
        self.gravity = GravityCheck()           # the IMU's accelerations carry gravity in m/s^2 (REP 145)
        self.log_throttle = KindThrottle(5.0)
        self.last_seen: float | None = None     # arrival time (monotonic) of the last detection
        self.last_image: float | None = None
        self.last_v: float | None = None
        self.lost = False                       # the last processed frame had no marker
        self.stale = True
        self.frames = self.detections = self.odoms = 0
        ns = topic_prefix(self, p["namespace_prefix"])
        self.pub_pose = self.create_publisher(PoseStamped, f"{ns}/aruco/marker_pose", MEASUREMENT_QOS)
        self.pub_odom = self.create_publisher(Odometry, f"{ns}/odom", MEASUREMENT_QOS)
        self.pub_stale = self.create_publisher(Bool, f"{ns}/aruco/stale", MEASUREMENT_QOS)
        if self.use_imu:    # first: with an IMU sample and an image both waiting, the executor serves the IMU first
            # best effort (matches any IMU driver) but 50 deep: while an image is being processed the
            # samples wait instead of being dropped (sensor-data QoS keeps 5: 0.1 s at 50 Hz; a busy
            # 2-core twin lost a quarter of them, docs/twin.md runs 36-38)
            imu_qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)
            self.create_subscription(Imu, f"{ns}/imu", self._on_imu, imu_qos)
        self.create_subscription(CameraInfo, p["camera_info_topic"], self._on_info, qos_profile_sensor_data)
        # sensor-data QoS by default (best effort: matches any camera driver, late frames are
        # worthless); image_reliable=true for lossless links such as recorded data or tests
        img_qos = (QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
                   if p["image_reliable"] else qos_profile_sensor_data)
        self.create_subscription(Image, p["image_topic"], self._on_image, img_qos)
        steady_timer(self, 0.1, self._check_stale)
        self.diag = Diagnostics(self, {"pose": self._report})

    def _set_marker_height(self, v: float) -> None:
        """A new height moves every position: the speed estimate restarts (no step in x reaches
        v_x), and the height check is redone on the next frame."""
        self._finish_pending()  # placed with the old height: out as it would have gone without the wait
        self.marker_height = v
        self.height_problem = None
        self.vel.reset()

    def _set_imu_accel_wait(self, v: float) -> None:
        self._finish_pending()
        self.imu_accel_wait = v
        if self._wait_timer is not None:     # made again with the new period at the next wait
            self.destroy_timer(self._wait_timer)
            self._wait_timer = None

    def _set_imu_timeout(self, v: float) -> None:
        self.imu_timeout = v
        self._set_filter()

    def _set_stale_timeout(self, v: float) -> None:
        self.stale_timeout = v
        self._set_filter(max_gap=v)

    def _make_velocity(self):
        v = self._vel_params
        if v["filter"] == "window":
            return VelocityEstimator(v["window"])
        if self.imu_accel:      # without acceleration samples it is exactly the constant-velocity filter
            return InertialVelocityEstimator(v["accel_noise"], v["position_noise"], max_gap=v["max_gap"],
                                             imu_accel_noise=v["imu_accel_noise"], accel_timeout=self.imu_timeout,
                                             hold=v["hold"])
        return KalmanVelocityEstimator(v["accel_noise"], v["position_noise"], max_gap=v["max_gap"])

    def _set_filter(self, **changes) -> None:
        """A velocity parameter changed: a new estimator (samples of the old one are not mixed in)."""
        self._finish_pending()  # with the filter it was measured for
        self._vel_params.update(changes)
        self.vel = self._make_velocity()

    # ------------------------------------------------------------------ inputs
    def _on_info(self, msg: CameraInfo) -> None:
        try:
            if msg.width == 0 or msg.height == 0:
                # REP 104: the calibrated image size; without it an image of another resolution
                # passes with these intrinsics (v_x half the truth: a review's fault injection)
                raise ValueError(f"image size {msg.width}x{msg.height}; expected the calibrated width and height")
            cam = CameraModel.from_camera_info(msg.k, msg.d, msg.width, msg.height, msg.distortion_model)
        except ValueError as exc:
            self.info_problem = f"CameraInfo invalid: {exc}"
            kept = "; keeping the previous one" if self.cam is not None else "; images ignored"
            self._log("warn", self.info_problem + kept)
            return
        self.info_problem = None
        old = self.cam
        self.cam, self.info_frame_id = cam, msg.header.frame_id
        if old is not None and not (np.array_equal(old.K, cam.K) and _same_distortion(old.D, cam.D)
                                    and (old.width, old.height) == (cam.width, cam.height)):
            # positions from the old intrinsics and the new differ by the calibration's change:
            # no speed across it (a 3 % recalibration read as v_x 0.54 for 0.37 m/s: a review)
            self._finish_pending()
            self.vel.reset()
            self.prior.reset()
            self.camera_model_changes += 1
            self._log("warn", f"the camera model changed (K, D or size; fx {old.K[0, 0]:.1f} -> {cam.K[0, 0]:.1f}, "
                              f"size {old.width}x{old.height} -> {cam.width}x{cam.height}): the speed estimate restarts")

    def _on_imu(self, msg: Imu) -> None:
        """Keep the IMU's roll and pitch by stamp. An IMU without orientation (REP 145: covariance[0]
        = -1), a bad quaternion or a zero stamp is not used, and says why in the diagnostics."""
        if msg.orientation_covariance[0] == -1.0:
            self.imu_problem = "IMU message has no orientation (orientation_covariance[0] = -1): tilt not used"
            return
        o = msg.orientation
        zr, zp = self.imu_zero
        try:
            w, x, y, z = level_orientation((o.w, o.x, o.y, o.z), zr, zp)     # the IMU's mounting taken off
            roll, pitch = roll_pitch(x, y, z, w)
        except ValueError as exc:
            self._imu_fault(f"IMU message rejected: {exc}")
            return
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        bad = stamp_problem(msg.header.stamp.sec, msg.header.stamp.nanosec, self.get_clock().now().nanoseconds, "IMU")
        if bad is not None:
            self._imu_fault(f"{bad}: tilt not used")
            return
        if self.imu and t <= self.imu[-1][0]:
            if t < self.imu[-1][0]:
                self.imu.clear()            # a bag loop or a restart: the older samples are another time line
            else:
                return
        self.imu.append((t, roll, pitch))
        self.imu_problem = None
        if self.imu_accel and msg.linear_acceleration_covariance[0] != -1.0 and hasattr(self.vel, "add_accel"):
            la = level_force((msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z), zr, zp)
            try:
                a_x = forward_acceleration(la, roll, pitch, self.yaw)
            except ValueError as exc:
                self._imu_fault(f"IMU acceleration rejected: {exc}")
                return
            # used only once a second of samples shows gravity in m/s^2 (an IMU in g passes the 4 g bound)
            self.gravity.add(t, la)
            gravity_problem = self.gravity.problem()
            if gravity_problem is None:
                if self.vel.add_accel(t, a_x):
                    self.accel_samples += 1
            elif self.gravity.mean_norm is not None:
                self._imu_fault(f"IMU acceleration not used: {gravity_problem}")
            if self.pending is not None and t >= self._stamp_s(self.pending[0]):
                self._finish_pending()

    def _imu_fault(self, why: str) -> None:
        """An IMU message not used: said in the diagnostics and a log line (per kind, throttled).
        Nothing else changes: the camera's speed goes on without the sample (an IMU that keeps
        failing must cost the tilt and the acceleration, not the odometry)."""
        self.imu_problem = why
        self.imu_faults += 1
        self._log("warn", why)

    def _log(self, level: str, msg: str) -> None:
        """Throttled per kind of problem: one does not hide another (rclpy throttles per call site,
        and a call site keeps one severity: hence a call per level)."""
        if not self.log_throttle.due(msg):
            return
        if level == "error":
            self.get_logger().error(msg)
        else:
            self.get_logger().warn(msg)

    def _tilt_at(self, t: float) -> tuple[float, float] | None:
        """The IMU's (roll, pitch) at image time t: the mean of the samples in (t - imu_window, t]
        when there are any (half a window late: 50 ms, 0.4 deg of an 8 deg/s tilt, 2 mm of x),
        else interpolated between the samples around t, or the nearest one when it is within
        imu_timeout of t; None without such a sample."""
        if not self.imu:
            return None
        if self.imu_window > 0.0:
            win = [s for s in self.imu if t - self.imu_window < s[0] <= t + 1e-6]
            if win:
                return (sum(s[1] for s in win) / len(win), sum(s[2] for s in win) / len(win))
        first, last = self.imu[0], self.imu[-1]
        if t >= last[0]:
            return (last[1], last[2]) if t - last[0] <= self.imu_timeout else None
        if t <= first[0]:
            return (first[1], first[2]) if first[0] - t <= self.imu_timeout else None
        for a, b in zip(self.imu, list(self.imu)[1:]):
            if a[0] <= t <= b[0]:
                if b[0] - a[0] > 2.0 * self.imu_timeout:       # a gap in the IMU's stream: the nearer, if close
                    near = a if t - a[0] <= b[0] - t else b
                    return (near[1], near[2]) if abs(t - near[0]) <= self.imu_timeout else None
                w = (t - a[0]) / (b[0] - a[0])
                return (a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2]))
        return None

    def _reject(self, why: str) -> None:
        """A frame that is not a measurement: no output, and the speed window restarts (the
        next v_x must come from consecutive measurements)."""
        self.image_problem = why
        self.vel.reset()
        self._log("error", why)

    @staticmethod
    def _stamp_s(stamp) -> float:
        return stamp.sec + stamp.nanosec * 1e-9

    def _finish_pending(self, timed_out: bool = False) -> None:
        """The image held back for the accelerometer: its v_x and odometry now, with every sample
        that came (after the wait, the newest one held, as without waiting)."""
        if self._wait_timer is not None:
            self._wait_timer.cancel()
        self._deadline_passed = False
        if self.pending is None:
            return
        stamp, x, T_base = self.pending
        self.pending = None
        self.imu_wait_timeouts += int(timed_out)     # ended without the covering sample
        v = self._speed(stamp, x)
        if v is not None:
            self._publish_odom(stamp, T_base, v)

    def _on_wait_timeout(self) -> None:
        """The wait's deadline. rclpy runs a ready timer before the subscriptions of the same
        wake-up, so IMU samples already queued (a node behind its inputs) have not been taken yet:
        the first expiry only marks the deadline, and those samples, taken right after it, may
        still end the wait; the next expiry (a period later: the IMU stopped) ends it regardless."""
        if self.pending is not None and not self._deadline_passed:
            self._deadline_passed = True
            return
        self._finish_pending(timed_out=True)

    def _speed_and_odom(self, stamp, x: float, T_base: np.ndarray) -> None:
        """v_x and the odometry of a detection, or, when the accelerometer is live and its sample
        covering the image's instant has not come yet, the same after at most imu_accel_wait."""
        if (self.imu_accel_wait > 0.0 and isinstance(self.vel, InertialVelocityEstimator)
                and self.vel.last_t is not None and self.vel.awaits_sample(self._stamp_s(stamp), self.imu_timeout)):
            self.pending = (stamp, x, T_base.copy())
            self.imu_waits += 1
            if self._wait_timer is None:
                self._wait_timer = steady_timer(self, self.imu_accel_wait, self._on_wait_timeout)
            else:
                self._wait_timer.reset()
            return
        v = self._speed(stamp, x)
        if v is not None:
            self._publish_odom(stamp, T_base, v)

    def _on_image(self, msg: Image) -> None:
        if self.pending is not None:    # the previous image's odometry first, in order
            self._finish_pending(timed_out=True)
        now = time.monotonic()
        self.last_image = now
        if self.cam is None:
            self.vel.reset()
            self.get_logger().info("waiting for a valid CameraInfo; image ignored", throttle_duration_sec=5.0)
            return
        cam = self.cam
        bad = stamp_problem(msg.header.stamp.sec, msg.header.stamp.nanosec, self.get_clock().now().nanoseconds, "image")
        if bad is not None:
            self._reject(f"{bad}; frame not used")      # no pose with a stamp nobody can judge the age of
            return
        if (self.match_info_frame and msg.header.frame_id and self.info_frame_id
                and msg.header.frame_id.lstrip("/") != self.info_frame_id.lstrip("/")):
            self._reject(f"image frame_id {msg.header.frame_id!r} differs from the CameraInfo's {self.info_frame_id!r}: "
                         "expected the calibration of this camera (check camera_info_topic; where the two name one "
                         "camera differently, set match_info_frame:=false)")
            return
        try:
            # the size first: a frame of another size is refused before it is copied and converted (a review:
            # a 36 MB frame was converted to grey, then refused)
            if msg.width and msg.height and cam.width and cam.height and (msg.width, msg.height) != (cam.width,
                                                                                                  cam.height):
                raise ImageEncodingError(f"image {msg.width}x{msg.height} differs from CameraInfo's "
                                         f"{cam.width}x{cam.height}; expected the calibrated size")
            gray = image_to_gray(msg.height, msg.width, msg.encoding, msg.step, bytes(msg.data))
            corners = self.detector.detect(gray)
            T_cam_marker = self.detector.pose(corners, cam, self.prior) if corners is not None else None
        except ImageEncodingError as exc:
            self._reject(str(exc))
            return
        except AmbiguousMarkerError as exc:       # no pose from this frame, and none chosen near the last one
            self.prior.reset()
            self._reject(str(exc))
            return
        except cv2.error as exc:   # a frame OpenCV cannot process must not end the node
            self._reject(f"OpenCV failed on this frame: {str(exc).strip().splitlines()[-1]}")
            return
        self.image_problem = None
        self.frames += 1
        self.lost = T_cam_marker is None
        if T_cam_marker is None:
            self.vel.reset()
            self.prior.reset()
            if self.last_seen is not None and now - self.last_seen > self.stale_timeout:
                self._set_stale(True)
            return
        T_pile_marker = self.T_pile_cam @ T_cam_marker
        if self.planar:  # the machine drives on the floor: keep x, y, z and heading only
            T_pile_marker = level(T_pile_marker)
            # ... and the marker's height is known: the ray through its centre (the height check is
            # set there; planar_motion is fixed and a marker_height change clears it)
            if self.marker_height > 0.0 and not self._on_plane(T_pile_marker, corners, cam):
                return
        T_base = T_pile_marker @ self.T_marker_base
        self.yaw = math.atan2(T_base[1, 0], T_base[0, 0])
        x_speed, source = float(T_pile_marker[0, 3]), "marker"
        tilt = None
        if self.planar and self.marker_height > 0.0 and self.use_imu:
            tilt = self._tilt_at(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
            if tilt is not None:
                db = self.imu_deadband
                tilt = tuple(math.copysign(max(0.0, abs(a) - db), a) for a in tilt)
        if tilt is not None:
            # the IMU says how the machine is tilted: base_link from the ray with that tilt, and
            # the published pose IS the tilted one (orientation: the IMU's roll and pitch with the
            # marker's heading; position: base_link raised as the tilt about the wheels on the
            # floor lifts it). The controllers were trained on the simulator's true tip: a
            # levelled pose put the tip of a machine pried 10 deg nose down 19 cm too high, the
            # actor drove on, and the supervisor judged that tip in the end zone (docs/twin.md
            # "Runs 43-46")
            yaw = math.atan2(T_base[1, 0], T_base[0, 0])
            contact_z = -(self.marker_height - float(self.marker_in_base[2]))
            p_base = tilted_base_position(self._ray, self.T_pile_cam, yaw, tilt[0], tilt[1], self.marker_in_base,
                                          self.wheelbase, contact_z)
            if p_base is None:
                self._reject("the camera ray through the marker does not meet the tilted marker's plane; expected a "
                             "camera above the marker (check camera_xyz, camera_rpy, marker_height)")
                return
            T_base = np.eye(4)
            T_base[:3, :3] = rpy_matrix(tilt[0], tilt[1], yaw)
            T_base[:3, 3] = p_base
            T_pile_marker = T_base @ self.T_base_marker
            x_speed, source = float(p_base[0]), "base_imu"
            self.tilted += 1
        if source != self.x_source:     # marker x and base_link x differ by the lever arm: no step into v_x
            self.vel.reset()
            self.x_source = source
        self.detections += 1
        self.last_seen = now
        self._set_stale(False)
        self._publish_pose(msg.header.stamp, T_pile_marker)
        self._speed_and_odom(msg.header.stamp, x_speed, T_base)

    def _on_plane(self, T_pile_marker: np.ndarray, corners: np.ndarray, cam: CameraModel) -> bool:
        """Replace the marker's position (in place) by the camera ray through its centre met with the
        plane z = marker_height. False (frame rejected) when the ray misses the plane, which only
        a wrong camera pose or height does. solvePnP's own height is kept as a check: far off
        marker_height means the calibration is wrong (diagnostics warn)."""
        h = self.marker_height
        try:
            self._ray = marker_centre_ray(corners, cam)
            pos = position_on_plane(self._ray, self.T_pile_cam, h)
        except (ValueError, cv2.error) as exc:
            self._reject(f"marker not usable: {str(exc).strip().splitlines()[-1]}")
            return False
        if pos is None:
            self._reject(f"the camera ray through the marker does not meet the plane z = marker_height = {h:g} m; "
                         "expected a camera above the marker (check camera_xyz, camera_rpy, marker_height)")
            return False
        z_pnp = float(T_pile_marker[2, 3])
        self.height_problem = (None if abs(z_pnp - h) <= HEIGHT_TOLERANCE else
                               f"marker seen at z = {z_pnp:.3f} m by solvePnP but marker_height is {h:g} m; expected "
                               f"within {HEIGHT_TOLERANCE:g} m (check marker_height, camera_xyz, marker_size)")
        T_pile_marker[:3, 3] = pos
        return True

    def _speed(self, stamp, x: float) -> float | None:
        """v_x from x: without an IMU the marker's own position (the articulation is locked and the
        machine drives straight and level, so every point of the rear frame moves with the same
        v_x, and the marker origin is free of the lever-arm noise that the marker's orientation
        jitter puts on base_link); with one, base_link's, placed with the IMU's tilt (a tilting
        machine's marker, 0.21 m above base_link, moves faster than base_link). None unless
        this detection is a new measurement in a run of consecutive ones."""
        t = stamp.sec + stamp.nanosec * 1e-9
        last = self.vel.last_t
        if not self.vel.add(t, x):
            self.stamp_problem = (f"image stamp {t:.3f} repeated: no speed from it" if t == last else
                                  f"image stamp went back from {last:.3f} to {t:.3f}: speed window restarted")
            return None
        v = self.vel.velocity()
        if v is None or not math.isfinite(v):
            return None
        self.stamp_problem = None
        self.last_v = v
        return v

    # ------------------------------------------------------------------ outputs
    def _publish_pose(self, stamp, T_marker) -> None:
        ps = PoseStamped()
        ps.header.stamp = stamp
        ps.header.frame_id = self.frame_id
        _fill_pose(ps.pose, T_marker)
        self.pub_pose.publish(ps)

    def _publish_odom(self, stamp, T_base, v: float) -> None:
        od = Odometry()
        od.header.stamp = stamp
        od.header.frame_id = self.frame_id
        od.child_frame_id = self.child_frame_id
        _fill_pose(od.pose.pose, T_base)
        cov = [0.0] * 36
        for i in range(3):
            cov[7 * i] = POSE_VAR
        for i in range(3, 6):
            cov[7 * i] = POSE_VAR * 4.0  # rad^2: orientation from a 0.12 m marker is ~2x less certain
        od.pose.covariance = cov
        od.twist.twist.linear.x = v
        # only v_x is measured: the other twist axes get a variance that says "not measured" (a fuser such as
        # robot_localization took the zeros as perfect knowledge; a ROS review, 2026-11-29)
        tc = [0.0] * 36
        for i in range(1, 6):
            tc[7 * i] = UNMEASURED_VAR
        tc[0] = SPEED_VAR[self._vel_params["filter"]]
        od.twist.covariance = tc
        self.pub_odom.publish(od)
        self.odoms += 1

    def _set_stale(self, s: bool) -> None:
        if s != self.stale:
            self.stale = s
            if s:
                self._finish_pending()
                self.vel.reset()
                self.get_logger().warn("marker lost: odometry stale", throttle_duration_sec=2.0)
            self.pub_stale.publish(Bool(data=s))

    def _check_stale(self) -> None:
        """10 Hz (steady clock): the marker (or the camera) gone for stale_timeout makes the
        estimate stale; the flag is republished every tick for late subscribers."""
        now = time.monotonic()
        seen = self.last_seen is not None and now - self.last_seen <= self.stale_timeout
        if not seen:
            self._set_stale(True)
        self.pub_stale.publish(Bool(data=self.stale))

    def _report(self):
        now = time.monotonic()
        values = {"frames": self.frames, "detections": self.detections, "odometry": self.odoms,
                  "stale": self.stale, "tilted_by_imu": self.tilted, "v_x_from": self.x_source,
                  "imu_accelerations": self.accel_samples, "imu_waits": self.imu_waits,
                  "imu_wait_timeouts": self.imu_wait_timeouts, "imu_rejected": self.imu_faults,
                  "camera_model_changes": self.camera_model_changes}
        if isinstance(self.vel, InertialVelocityEstimator):
            values["accel_bias"] = self.vel.bias_estimate()
            values["position_jumps"] = self.vel.jumps     # displacements the filter started again after
        if self.last_v is not None:
            values["last_v_x"] = self.last_v
        if self.last_image is None:
            return WARN, "no image yet" + ("" if self.cam else " and no valid CameraInfo"), values
        # the root cause first: a missing calibration, then the last image's defect, then silence
        if self.cam is None:
            return ERROR, self.info_problem or "no CameraInfo yet: images ignored", values
        if self.image_problem is not None:
            return ERROR, self.image_problem, values
        if now - self.last_image > self.stale_timeout:
            return ERROR, f"no image for {now - self.last_image:.1f} s", values
        if self.last_seen is None:
            return WARN, "marker not seen yet", values
        lost = now - self.last_seen
        if lost > self.stale_timeout:
            return ERROR, f"marker lost for {lost:.1f} s: odometry stopped", values
        if self.info_problem is not None:
            return WARN, self.info_problem + "; using the previous one", values
        if self.stamp_problem is not None:
            return WARN, self.stamp_problem, values
        if self.height_problem is not None:
            return WARN, self.height_problem, values
        if self.use_imu and self.imu_problem is not None:
            return WARN, self.imu_problem, values
        if self.lost:
            return WARN, f"marker lost for {lost:.1f} s", values
        return OK, "marker tracked", values


def _same_distortion(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal coefficients, the shorter padded with zeros (5 zeros and 8 zeros are one model)."""
    n = max(len(a), len(b))
    return np.array_equal(np.pad(a, (0, n - len(a))), np.pad(b, (0, n - len(b))))


def _fill_pose(pose, T) -> None:
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in T[:3, 3])
    q = quaternion_xyzw(T[:3, :3])
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q


def main(args=None) -> int:
    return run_node(ArucoPoseNode, "aruco_pose_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
