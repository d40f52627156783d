"""`ros2 run lhd_sim_node twin_node`: the digital twin. The MuJoCo LHD as the real machine's
stack sees the real one: the Arduino Due on a serial line, an overhead camera and a LiDAR.

Node name `lhd_twin`. It owns one LhdSimulator stepped in real time in 20 ms chunks (the FEE
period) by the device loop of sim_due.SimDue (a thread on the steady clock), and:
* speaks the DEVICE side of docs/serial_protocol.md on a pseudo-terminal behind the symlink
  `link` (default /tmp/lhd_twin_due): the bridge node opens it as the machine (`port`). Firmware
  semantics (watchdog 250 ms, wheel set-point clamped to [0, 2.7] rad/s, no lowering / forward
  tilt, valves closed at the joint limits, e-stop), ternary valves at full hydraulic speed,
  sensor frames at 100 Hz, load-cell frames at 10 Hz with the simulator's loaded mass
  (lhd_sim_node/sim_due.py has the details and the motor constants);
* publishes the simulated sensors (sim_sensors.py): `image_topic` (/camera/image_raw, mono8) and
  `camera_info_topic` (/camera/camera_info) at `camera_fps`, `scan_topic` (/scan, LaserScan) at
  `lidar_hz`; the camera's and LiDAR's poses, the marker and its place on the machine come from
  `machine_params`, the ROS parameter file the real nodes get (config/real_machine.yaml: its
  `aruco_pose_node` and `lidar_slope_node` sections; '' = those nodes' defaults), so the twin and
  the nodes cannot disagree on a pose;
* ground truth under <prefix>/twin/truth/ at `truth_hz`: odom (nav_msgs/Odometry, base_link in
  the pile frame, twist.linear.x = v_x), drift (Float64MultiArray [front, rear] as 0/1),
  loaded_mass (Float64 kg), tip (geometry_msgs/PointStamped, the bucket tip), joint_states
  (sensor_msgs/JointState: boom, bucket and the four wheels as the simulator has them); once per
  pile (latched): slope (Float64 rad), zones (Float64MultiArray, task.zones.Zones.as_list()) and
  slice_slope (Float64 rad): the slope of the pile's slice in the LiDAR's scan plane (VoxelPile.slice_slope
  at the LiDAR's y), what a scanner can measure at best; on a plane pile it is the slope, on a rough one
  (pile_relief_sd) it differs from it by the relief of that slice;
* <prefix>/twin/truth/camera_lag (std_msgs/Float64MultiArray [stamp s, lag s], one per image
  published): how long after the instant its stamp names the image left the twin (rendering, and
  the twin's own lateness when the simulation runs behind the wall clock): `lhd up twin`
  subtracts it from the odometry's age to give the stack's own latency;
* <prefix>/twin/device/commands (std_msgs/Float64MultiArray at `command_trace_hz`): every valid
  command frame the device read off the serial line since the last message, one row each
  [wall time s, monotonic time s, wheel_setpoint rad/s, valve_boom, valve_bucket, enable 0/1]
  (layout: dim[0] rows, dim[1] the 6 columns), the times taken when the device read the bytes;
  `lhd bench twin` measures the camera-to-serial latency with it;
* <prefix>/twin/markers (visualization_msgs/MarkerArray at `markers_hz`): the pile's surface, the
  zones, the bucket tip's trajectory, the FEE force (twin_markers.py);
* attempts: the real stack's supervisor arms and ends them. The twin watches <prefix>/episode;
  once an ended attempt (success, failure, timeout, estop, lost_input, aborted) is weighed (its
  status carries a finite loaded_mass), and at least `reset_delay` s after the end (at the latest
  `weigh_timeout` s after it, weighed or not), it makes a new pile (pile k: seed + k, slopes_deg cycling, material) and puts the machine in the
  attack pose with the tip d_init inside the pile (the simulator's own reset: the paper's episode
  starts after the bucket hit the pile), or d_attack before the toe at rest with
  `start_pose:=approach`. Service ~/reset (std_srvs/Trigger) does it on demand; the first pile is
  made at start;
* /diagnostics: the device (firmware state, frames), real time (real-time factor, overruns: a
  20 ms chunk simulated more than a chunk late; resyncs: the loop fell 5 chunks behind and gave
  the backlog up; stepping CPU), the pile / attempt, the sensors.
`estop` (run time) presses the simulated machine's emergency-stop button.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from lhd_loading_ros.perception.synthetic import DrawPoint
from lhd_loading_ros.ros.diagnostics import OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import LATCHED_QOS, MEASUREMENT_QOS, STATUS_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.task.attempt import ENDED
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.imu_mount import mount_matrix, zero_problem
from lhd_loading_ros.task.randomization import Conditions

from . import sim_sensors as ss
from .sim_due import SimDue
from .simulator import MATERIALS, WHEELS, LhdSimulator
from .twin_markers import marker_array

# QoS (lhd_loading_ros.ros.qos): truth, images, camera info and scans MEASUREMENT_QOS (reliable,
# keep-last 5: matches reliable subscribers such as the recorder or an ArUco node with
# image_reliable, and best-effort sensor-data subscribers alike; a short queue never delays a fresh
# frame behind old ones); slope and zones change once per pile: LATCHED_QOS (a late subscriber
# gets the current pile's); the attempt status is read with STATUS_QOS, as the supervisor
# publishes it (transient local). Markers: MEASUREMENT_QOS (the next array replaces the last).
START_POSES = ("attack", "approach")
RESET_TICK = 0.05       # s, how often the reset schedule is checked (steady clock)


def parse_slopes(value) -> list[float]:
    if isinstance(value, (list, tuple)):
        value = ",".join(str(v) for v in value)
    text = str(value).strip()
    return [float(v) for v in text.split(",")] if text else []


def machine_sections(path: str) -> tuple[dict | None, dict | None]:
    """The `aruco_pose_node` and `lidar_slope_node` sections of a ROS parameter file ('' -> the
    nodes' defaults); ValueError naming the file when it cannot be read."""
    if not path:
        return None, None
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"parameter 'machine_params' = {path!r}: cannot read it as a ROS parameter file ({exc}); "
                         "expected a file like config/real_machine.yaml") from None
    if not isinstance(doc, dict):
        raise ValueError(f"parameter 'machine_params' = {path!r}: not a ROS parameter file (a mapping of node "
                         "names to ros__parameters expected)")
    # as rcl gives them to the two nodes in the root namespace, where `lhd up twin` runs them (the shipped file keys
    # its sections /**/<node>, so that they reach the nodes under a namespace too)
    from lhd_loading_ros.ros.params_file import params_of

    return params_of(doc, "/aruco_pose_node") or None, params_of(doc, "/lidar_slope_node") or None


def _weighed(status_values: dict) -> bool:
    """The ended attempt's status carries its mass (the load cell's or the operator's)."""
    try:
        return math.isfinite(float(status_values.get("loaded_mass", "nan")))
    except ValueError:
        return False


class TwinNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_twin", **node_kwargs)
        self.params = Params(self, [
            Param("config", "", "lhd_params.yaml to use; empty: found automatically (LHD_CONFIG, then the package's)"),
            Param("machine_params", "", "ROS parameter file of the real nodes (config/real_machine.yaml): the camera, "
                  "marker and LiDAR poses of its aruco_pose_node and lidar_slope_node sections; empty: those nodes' "
                  "defaults"),
            Param("link", "/tmp/lhd_twin_due", "symlink to the device's pseudo-terminal (the bridge's `port`)"),
            Param("namespace_prefix", "/lhd", "topic prefix in the root namespace (under a namespace, the namespace)"),
            Param("seed", 0, "pile k (from 0) uses seed + k", lo=0, hi=2**31 - 1),
            Param("slopes_deg", "", "pile slopes to cycle through, degrees ('15,20,25,30'; empty: random in the "
                  "config's range); a change applies from the next pile", dynamic_type=True, check=self._check_slopes,
                  on_change=self._set_slopes),
            Param("material", "random", "pile material (random: drawn per pile); from the next pile",
                  choices=(*MATERIALS, "random"), on_change=self._set_material),
            Param("pile_relief_sd", 0.0, "m, sd of a random relief of the pile's surface about its plane (0: a "
                  "plane; task/pile.py VoxelPile.roughen; `lhd eval --stress rough` uses 0.03); from the next pile",
                  lo=0.0, hi=0.2, on_change=lambda v: setattr(self, "relief_sd", v)),
            Param("pile_relief_corr", 0.15, "m, the relief's correlation length; from the next pile", lo=0.01, hi=2.0,
                  on_change=lambda v: setattr(self, "relief_corr", v)),
            Param("start_pose", "attack", "attack: the tip driven d_init into the pile (the simulator's reset); "
                  "approach: at rest, the tip d_attack before the toe", choices=START_POSES,
                  on_change=lambda v: setattr(self, "start_pose", v)),
            Param("start_heading_deg", 0.0, "deg, the machine's heading where it is put (positive: nose to +y): a "
                  "machine placed by hand; the supervisor refuses to arm beyond its max_heading_deg",
                  lo=-20.0, hi=20.0, on_change=lambda v: setattr(self, "start_heading", math.radians(v))),
            Param("start_lateral_offset", 0.0, "m, the bucket lip's centre off the pile's axis where the machine is put",
                  lo=-0.3, hi=0.3, on_change=lambda v: setattr(self, "start_lateral", v)),
            Param("d_attack", -1.0, "m, the tip's distance before the toe where the machine is put (negative: drawn "
                  "from the config's range)", lo=-1.0, hi=5.0, on_change=lambda v: setattr(self, "d_attack", v)),
            Param("auto_reset", True, "a new pile reset_delay s after the attempt ended",
                  on_change=lambda v: setattr(self, "auto_reset", v)),
            Param("reset_delay", 2.5, "s from an ended attempt to the new pile at the earliest; the pile is kept "
                  "until the attempt is weighed (its status carries a loaded_mass)", lo=0.0, hi=60.0,
                  on_change=lambda v: setattr(self, "reset_delay", v)),
            Param("weigh_timeout", 20.0, "s after the end: a new pile even if the attempt was not weighed (no load "
                  "cell, no operator)", lo=0.0, hi=600.0, on_change=lambda v: setattr(self, "weigh_timeout", v)),
            Param("estop", False, "the simulated machine's emergency-stop button pressed",
                  on_change=self._set_estop),
            Param("load_cell", True, "the device has the bucket's load cell (load-cell frames at 10 Hz)"),
            Param("arm_zero_error_deg", [0.0, 0.0], "deg, the device's boom and bucket angles read this far off the "
                  "true ones (a sensor zeroed off the attack pose; the bridge's boom_zero / bucket_zero correct it: "
                  "docs/real_machine.md Calibration step 7)", length=2,
                  check=lambda v: None if all(abs(float(x)) <= 20.0 for x in v) else "expected each within +-20 deg"),
            Param("arm_angle_noise_deg", 0.0, "deg, noise (standard deviation) on each sample of the device's boom and "
                  "bucket angles: a potentiometer's ADC (docs/real_machine.md Calibration step 8)", lo=0.0, hi=5.0),
            Param("arm_rate_window", 0.1, "s, the device firmware's rate window: its boom and bucket rates are the "
                  "differences of its angles over it (arm_rate.h; 0.01, one frame, is the firmware before 2026-11-29)",
                  lo=0.005, hi=0.5),
            Param("truth_hz", 50.0, "Hz, ground-truth topics", lo=1.0, hi=100.0),
            Param("imu_hz", 0.0, "Hz, <prefix>/imu: the rear frame's orientation as an IMU on it would give it "
                  "(0: none; the paper's machine has none: `lhd up twin --imu`)", lo=0.0, hi=200.0),
            Param("imu_noise_deg", 0.1, "deg, roll and pitch noise of the IMU (standard deviation)", lo=0.0, hi=10.0),
            Param("imu_accel_noise", 0.05, "m/s^2, white noise of each accelerometer sample (standard deviation; "
                  "a MEMS IMU's 150-300 ug/sqrt(Hz) over its 25 Hz band is 0.007-0.015: a margin)", lo=0.0, hi=10.0),
            Param("imu_mount_deg", [0.0, 0.0], "deg, [roll, pitch] of the IMU's mounting on the rear frame (its axes "
                  "turned so, in base_link's: Rx(roll) Ry(pitch); positive pitch: nose down): both its orientation and "
                  "its accelerometer see it, as a sensor bolted on askew", length=2, check=zero_problem),
            Param("imu_accel_bias", 0.1, "m/s^2, the accelerometer's bias on each axis is drawn once from "
                  "U(-b, b) (a calibrated MEMS IMU's residual bias: tens of mg)", lo=0.0, hi=10.0),
            Param("markers_hz", 5.0, "Hz, the MarkerArray (0: none)", lo=0.0, hi=30.0),
            Param("command_trace_hz", 10.0, "Hz, <prefix>/twin/device/commands: the command frames read off the "
                  "line (0: none)", lo=0.0, hi=100.0),
            Param("camera_fps", 30.0, "Hz, camera frames (0: no camera)", lo=0.0, hi=60.0),
            Param("image_topic", "/camera/image_raw", "camera images (mono8)"),
            Param("camera_info_topic", "/camera/camera_info", "camera intrinsics"),
            Param("camera_frame_id", "camera", "frame of the images"),
            Param("image_width", 640, "px", lo=16, hi=4096),
            Param("image_height", 480, "px", lo=16, hi=4096),
            Param("focal_px", 0.0, "focal length in px (0: 0.94 x width, a 56 deg field of view)", lo=0.0, hi=1e5),
            Param("camera_noise", 2.0, "grey levels, sensor noise (standard deviation)", lo=0.0, hi=100.0),
            Param("camera_blur", 1.0, "px, optical blur (3 sigma)", lo=0.0, hi=50.0),
            Param("camera_exposure", 1.0, "gain on the scene's brightness", lo=0.01, hi=10.0),
            Param("camera_dropout", 0.0, "probability that a frame is lost", lo=0.0, hi=0.99),
            Param("lidar_hz", 5.0, "Hz, LiDAR scans (0: no LiDAR)", lo=0.0, hi=50.0),
            Param("scan_topic", "/scan", "LiDAR scans"),
            Param("lidar_frame_id", "lidar", "frame of the scans"),
            Param("lidar_beams", 720, "beams per scan", lo=2, hi=10000),
            Param("lidar_noise", 0.01, "m, range noise (standard deviation)", lo=0.0, hi=1.0),
            Param("lidar_outliers", 0.02, "fraction of beams with a random range", lo=0.0, hi=0.99),
            Param("lidar_clutter", True, "the draw point's ceiling, drawbell and side walls in the scans"),
            Param("frame_id", "pile", "frame of the truth poses and markers"),
            Param("base_frame_id", "base_link", "child frame of the truth odometry"),
        ])
        gp = self.params.__getitem__
        cfg = load_config(gp("config") or None)
        ep = cfg["paper"]["episode"]
        self.alpha_range_deg = (ep["alpha_min_deg"], ep["alpha_max_deg"])
        self.d_attack_range = (ep["d_attack_min"], ep["d_attack_max"])
        why = self._check_slopes(gp("slopes_deg"))     # the range is known now
        if why:
            raise ValueError(f"parameter 'slopes_deg' = {gp('slopes_deg')!r} is invalid: {why}")
        self._set_slopes(gp("slopes_deg"))
        self._set_material(gp("material"))
        self.seed, self.start_pose, self.d_attack = gp("seed"), gp("start_pose"), gp("d_attack")
        self.relief_sd, self.relief_corr = gp("pile_relief_sd"), gp("pile_relief_corr")
        self.start_heading, self.start_lateral = math.radians(gp("start_heading_deg")), gp("start_lateral_offset")
        self.auto_reset, self.reset_delay, self.weigh_timeout = gp("auto_reset"), gp("reset_delay"), gp("weigh_timeout")
        self.frame_id, self.base_frame_id = gp("frame_id"), gp("base_frame_id")
        aruco, lidar = machine_sections(gp("machine_params"))
        self.camera = None
        if gp("camera_fps") > 0:
            self.camera = ss.CameraModel.from_params(
                aruco, gp("image_width"), gp("image_height"), gp("focal_px") or None, noise=gp("camera_noise"),
                blur=gp("camera_blur"), exposure=gp("camera_exposure"), dropout=gp("camera_dropout"))
        self.lidar = None
        if gp("lidar_hz") > 0:
            self.lidar = ss.LidarModel.from_params(lidar, n=gp("lidar_beams"), noise=gp("lidar_noise"),
                                                   outliers=gp("lidar_outliers"))
        self.clutter = DrawPoint(machine=False) if gp("lidar_clutter") else None
        ns = topic_prefix(self, gp("namespace_prefix"))
        self.ns = ns

        self.sim = LhdSimulator(cfg)
        self.wheel_radius = self.sim.wheel_radius
        self._wheel_q = [int(self.sim.model.jnt_qposadr[self.sim.model.joint(w).id]) for w in WHEELS]
        self.trail = ss.TipTrail()
        self.piles = 0                      # piles made (the current one is piles - 1)
        self.pile_slope_deg = float("nan")
        self.reset_reason = ""
        self.resets = 0
        self._rng_sensors = np.random.default_rng(self.seed + 7_919)
        self._attempt = None                # (state, episode) of the latest /episode status
        self._handled_end = None            # the ended (state, episode) a reset was scheduled for
        self._reset_at = None               # monotonic time of the scheduled reset
        self._ended_at = None               # monotonic time the handled end was seen (waiting for its weighing)
        self.camera_frames = self.camera_dropped = self.scans = 0
        self.marker_visible = None
        self._window = {"t": time.monotonic(), "sim": 0.0, "chunks": 0, "overruns": 0, "resyncs": 0, "busy": 0.0}
        self._clock_offset_ns: int | None = None    # ROS time - monotonic time, for stamps (_stamp_of)

        t = time.perf_counter()
        self._new_pile("start")             # before the device loop: nothing else holds the simulator yet
        # one chunk at rest before the real-time loop: loads the compiled FEE kernel (about 0.5 s on
        # its first call, which the attack of `reset` makes but an approach pose does not), so the
        # loop's first chunk is not late
        self.sim.advance(np.zeros(3))
        self.first_reset_s = time.perf_counter() - t
        self.due = SimDue(self.sim, link=gp("link"), load_cell=gp("load_cell"), on_chunk=self._on_chunk,
                          arm_angle_noise=math.radians(gp("arm_angle_noise_deg")), rate_window=gp("arm_rate_window"),
                          noise_seed=int(gp("seed")))
        self.due.estop = gp("estop")
        self.due.arm_zero_error = tuple(math.radians(float(x)) for x in gp("arm_zero_error_deg"))

        self.pub_odom = self.create_publisher(Odometry, f"{ns}/twin/truth/odom", MEASUREMENT_QOS)
        self.pub_drift = self.create_publisher(Float64MultiArray, f"{ns}/twin/truth/drift", MEASUREMENT_QOS)
        self.pub_mass = self.create_publisher(Float64, f"{ns}/twin/truth/loaded_mass", MEASUREMENT_QOS)
        self.pub_tip = self.create_publisher(PointStamped, f"{ns}/twin/truth/tip", MEASUREMENT_QOS)
        self.pub_js = self.create_publisher(JointState, f"{ns}/twin/truth/joint_states", MEASUREMENT_QOS)
        self.pub_slope = self.create_publisher(Float64, f"{ns}/twin/truth/slope", LATCHED_QOS)
        self.pub_zones = self.create_publisher(Float64MultiArray, f"{ns}/twin/truth/zones", LATCHED_QOS)
        self.pub_slice_slope = self.create_publisher(Float64, f"{ns}/twin/truth/slice_slope", LATCHED_QOS)
        self.pub_markers = self.create_publisher(MarkerArray, f"{ns}/twin/markers", MEASUREMENT_QOS)
        # reliable keep-last 5 (MEASUREMENT_QOS): each message holds the frames since the last one
        self.pub_device_cmds = self.create_publisher(Float64MultiArray, f"{ns}/twin/device/commands", MEASUREMENT_QOS)
        self.pub_img = self.create_publisher(Image, gp("image_topic"), MEASUREMENT_QOS)
        self.pub_camera_lag = self.create_publisher(Float64MultiArray, f"{ns}/twin/truth/camera_lag", MEASUREMENT_QOS)
        self.pub_info = self.create_publisher(CameraInfo, gp("camera_info_topic"), MEASUREMENT_QOS)
        self.pub_scan = self.create_publisher(LaserScan, gp("scan_topic"), MEASUREMENT_QOS)
        self.camera_frame_id, self.lidar_frame_id = gp("camera_frame_id"), gp("lidar_frame_id")
        self.create_subscription(DiagnosticStatus, f"{ns}/episode", self._on_episode, STATUS_QOS)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self._publish_pile()

        # every timer on the steady clock: the twin is the machine, its time is the wall clock's
        steady_timer(self, 1.0 / gp("truth_hz"), self._publish_truth)
        self.pub_imu = None
        if gp("imu_hz") > 0:
            self.pub_imu = self.create_publisher(Imu, f"{ns}/imu", MEASUREMENT_QOS)
            self._imu_rng = np.random.default_rng([gp("seed"), 145])   # reproducible with the twin's seed
            self._imu_noise = math.radians(gp("imu_noise_deg"))
            self._accel_noise = gp("imu_accel_noise")
            self._accel_bias = self._imu_rng.uniform(-1.0, 1.0, 3) * gp("imu_accel_bias")
            mr, mp = (math.radians(float(x)) for x in gp("imu_mount_deg"))
            self._imu_mount = (mr, mp)
            self._imu_mount_R = mount_matrix(mr, mp)   # the IMU's axes in base_link's (task/imu_mount.py)
            self._imu_prev = None           # (pile, instant, world velocity) of the previous sample
            steady_timer(self, 1.0 / gp("imu_hz"), self._publish_imu)
        steady_timer(self, RESET_TICK, self._check_reset)
        if gp("markers_hz") > 0:
            steady_timer(self, 1.0 / gp("markers_hz"), self._publish_markers)
        self.command_trace = gp("command_trace_hz") > 0
        if self.command_trace:
            steady_timer(self, 1.0 / gp("command_trace_hz"), self._publish_device_commands)
        if self.camera is not None:
            self._info = self._camera_info()
            steady_timer(self, 1.0 / gp("camera_fps"), self._publish_image)
        if self.lidar is not None:
            self.scan_time = 1.0 / gp("lidar_hz")
            steady_timer(self, self.scan_time, self._publish_scan)
        self.diagnostics = Diagnostics(self, {"device": self._diag_device, "real time": self._diag_realtime,
                                              "pile": self._diag_pile, "sensors": self._diag_sensors},
                                       hardware_id=f"twin {gp('link')}")
        self.due.start()
        self.get_logger().info(f"twin up: device on {self.due.path} (link {gp('link')}), pile {self.piles - 1} "
                               f"{self.pile_slope_deg:.1f} deg {self.sim.material}, camera "
                               f"{gp('camera_fps'):g} fps, LiDAR {gp('lidar_hz'):g} Hz, topics under {ns}")

    # ------------------------------------------------------------------ parameters
    def _check_slopes(self, value) -> str | None:
        try:
            vals = parse_slopes(value)
        except ValueError:
            return "expected comma-separated degrees such as '15,20,25,30' (empty: a random slope per pile)"
        lo, hi = getattr(self, "alpha_range_deg", (-math.inf, math.inf))   # known once the config is read
        bad = [v for v in vals if not lo <= v <= hi]
        if bad:
            return f"{bad} outside the config's range [{lo:g}, {hi:g}] degrees"
        return None

    def _set_slopes(self, value) -> None:
        self.slopes = parse_slopes(value)

    def _set_material(self, value: str) -> None:
        self.material = None if value == "random" else value

    def _set_estop(self, value: bool) -> None:
        self.due.estop = value
        self.get_logger().warn("emergency stop PRESSED on the simulated machine" if value
                               else "emergency stop released on the simulated machine")

    # ------------------------------------------------------------------ piles
    def _new_pile(self, why: str) -> None:
        """Pile k = self.piles: its own generator (seed + k), slope slopes[k % n] (or random),
        the machine in the start pose. Holds the device's lock (when the loop runs)."""
        k = self.piles
        rng = np.random.default_rng(self.seed + k)
        alpha = math.radians(self.slopes[k % len(self.slopes)]) if self.slopes else None
        d_attack = self.d_attack if self.d_attack >= 0 else None
        lock = self.due.lock if hasattr(self, "due") else None
        if lock is not None:
            lock.acquire()
        try:
            if self.start_pose == "attack":
                self.sim.reset(rng, alpha=alpha, material=self.material, d_attack=d_attack,
                               conditions=Conditions(surface_sd=self.relief_sd, surface_corr=self.relief_corr,
                                                     heading_deg=math.degrees(self.start_heading),
                                                     lateral_offset=self.start_lateral))
            else:
                self.sim.new_pile(rng, alpha, self.material, surface_sd=self.relief_sd, surface_corr=self.relief_corr)
                self.sim.place_machine(d_attack if d_attack is not None else rng.uniform(*self.d_attack_range),
                                       self.start_heading, self.start_lateral)
            self.trail.clear()
            self.pile_slope_deg = math.degrees(self.sim.pile.alpha)
            if lock is not None:
                self.due.skip_backlog()     # the chunks due while the pile was made are not simulated
            self.piles += 1                 # under the lock: a sensor that reads the state reads its pile
        finally:
            if lock is not None:
                lock.release()
        self.reset_reason = why

    def _publish_pile(self) -> None:
        lidar_y = float(self.lidar.T_pile_sensor[1, 3]) if self.lidar is not None else 0.0
        with self.due.lock:
            alpha, zones = float(self.sim.pile.alpha), self.sim.zones.as_list()
            slice_alpha = float(self.sim.pile.slice_slope(lidar_y))
        self.pub_slice_slope.publish(Float64(data=slice_alpha))     # before the slope, which marks a new pile
        self.pub_slope.publish(Float64(data=alpha))
        self.pub_zones.publish(Float64MultiArray(data=[float(v) for v in zones]))

    def reset(self, why: str) -> str:
        self._reset_at = None
        self._new_pile(why)
        # a new pile ends the wait for the last attempt's weighing too (after the pile is made: a reset that
        # fails keeps weigh_timeout's): a ~/reset while it waited (an attempt that never ran is never weighed)
        # would otherwise be followed by weigh_timeout's reset, mid-attempt
        self._ended_at = None
        self.resets += 1
        self._publish_pile()
        text = (f"pile {self.piles - 1}: {self.pile_slope_deg:.1f} deg, {self.sim.material}, machine in the "
                f"{self.start_pose} pose ({why})")
        self.get_logger().info(text)
        return text

    def _on_reset(self, request, response):
        try:
            response.message = self.reset("~/reset")
            response.success = True
        except Exception as exc:  # noqa: BLE001 - an attack that failed (AttackError) is reported, not fatal
            response.success, response.message = False, f"reset failed: {exc}"
            self.get_logger().error(response.message)
        return response

    def _on_episode(self, msg: DiagnosticStatus) -> None:
        vals = {kv.key: kv.value for kv in msg.values}
        key = (vals.get("state", ""), vals.get("episode", ""))
        self._attempt = key
        now = time.monotonic()
        if key[0] in ENDED and key != self._handled_end:
            self._handled_end, self._ended_at, self._reset_at = key, now, None
        if key == self._handled_end and self._ended_at is not None and self.auto_reset and self._reset_at is None:
            # the pile stays until the supervisor has weighed the attempt (a new pile empties the
            # bucket: weighing after it read 0.4 kg for a 38 kg load once); weigh_timeout caps the wait
            if _weighed(vals):
                self._reset_at = max(now, self._ended_at + self.reset_delay)
                self._ended_at = None

    def _check_weigh_timeout(self) -> None:
        if self._ended_at is not None and self._reset_at is None and self.auto_reset and \
                time.monotonic() - self._ended_at >= max(self.weigh_timeout, self.reset_delay):
            self.get_logger().warn(f"attempt {self._handled_end[1]} not weighed {self.weigh_timeout:.0f} s after its "
                                   "end: new pile anyway")
            self._reset_at, self._ended_at = time.monotonic(), None

    def _check_reset(self) -> None:
        self._check_weigh_timeout()
        if self._reset_at is not None and time.monotonic() >= self._reset_at:
            try:
                self.reset(f"attempt {self._handled_end[1]} ended: {self._handled_end[0]}")
            except Exception as exc:  # noqa: BLE001
                self.get_logger().error(f"reset failed: {exc}")

    # ------------------------------------------------------------------ truth
    def _on_chunk(self, due) -> None:
        """After each 20 ms chunk, with the simulator's lock held: the tip's trajectory."""
        self.trail.add(self.sim._site_xpos[self.sim.sid_tip])

    def _state_and_stamp(self):
        """base_link's state as the machine is now (between chunks) and the ROS stamp of the
        instant it belongs to: now, or, when the simulation runs late, the newest simulated
        instant (the message then reports the past, stamped as such)."""
        pos, quat, v_x, t_state = self.due.base_state_at(time.monotonic())
        return pos, quat, v_x, self._stamp_of(t_state)

    def _stamp_of(self, t_mono: float):
        """The ROS stamp of monotonic instant t_mono. One fixed offset between the two clocks
        (measured at start): stamps of successive states never step back by the clocks' jitter,
        which would restart the ArUco node's speed filter."""
        if self._clock_offset_ns is None:
            self._clock_offset_ns = self.get_clock().now().nanoseconds - int(time.monotonic() * 1e9)
        return Time(nanoseconds=self._clock_offset_ns + int(round(t_mono * 1e9))).to_msg()

    def _publish_imu(self) -> None:
        """Orientation: the machine's true orientation turned by a small random roll and pitch (the
        IMU's noise): w, x, y, z of q_true * q_noise. Linear acceleration: the specific force of
        base_link's MEAN acceleration since the previous sample (the change of its world velocity
        over the interval: an IMU's anti-aliased output, not the contact chatter of one 4 ms step),
        in its own axes, plus a fixed bias and white noise; none (covariance -1) for the first
        sample of a pile (the machine was put there, not driven)."""
        with self.due.lock:
            _, quat, v3, t_state = self.due.base_motion_at(time.monotonic())
            pile = self.piles
        stamp = self._stamp_of(t_state)
        roll, pitch = self._imu_rng.normal(0.0, self._imu_noise, 2) if self._imu_noise > 0 else (0.0, 0.0)
        m = Imu()
        m.header.stamp, m.header.frame_id = stamp, self.base_frame_id
        o = m.orientation
        o.w, o.x, o.y, o.z = ss.imu_orientation(ss.imu_orientation(quat, *self._imu_mount), roll, pitch)
        var = self._imu_noise ** 2
        m.orientation_covariance[0] = m.orientation_covariance[4] = m.orientation_covariance[8] = var
        m.angular_velocity_covariance[0] = -1.0        # REP 145: -1 = not provided
        prev, self._imu_prev = self._imu_prev, (pile, t_state, v3)
        if prev is not None and prev[0] == pile and t_state - prev[1] > 1e-4:
            a_world = (v3 - prev[2]) / (t_state - prev[1])
            f = self._imu_mount_R.T @ ss.imu_specific_force(quat, a_world) + self._accel_bias
            if self._accel_noise > 0:
                f = f + self._imu_rng.normal(0.0, self._accel_noise, 3)
            la = m.linear_acceleration
            la.x, la.y, la.z = (float(c) for c in f)
            acc_var = self._accel_noise ** 2
            m.linear_acceleration_covariance[0] = m.linear_acceleration_covariance[4] = acc_var
            m.linear_acceleration_covariance[8] = acc_var
        else:
            m.linear_acceleration_covariance[0] = -1.0
        self.pub_imu.publish(m)

    def _publish_truth(self) -> None:
        sim = self.sim
        with self.due.lock:
            d = sim.data
            pos, quat, v_x, stamp = self._state_and_stamp()
            wz = float(d.qvel[5])
            s = sim.state()
            mass = float(sim.loaded_mass)
            wheels = d.qvel[sim.wheel_dof].tolist()
            wheel_q = d.qpos[self._wheel_q].tolist()
        od = Odometry()
        od.header.stamp, od.header.frame_id, od.child_frame_id = stamp, self.frame_id, self.base_frame_id
        p, o = od.pose.pose.position, od.pose.pose.orientation
        p.x, p.y, p.z = (float(c) for c in pos)
        o.w, o.x, o.y, o.z = (float(c) for c in quat)
        od.twist.twist.linear.x = float(v_x)
        od.twist.twist.angular.z = wz
        self.pub_odom.publish(od)
        self.pub_drift.publish(Float64MultiArray(data=[float(bool(s.drift_front)), float(bool(s.drift_rear))]))
        self.pub_mass.publish(Float64(data=mass))
        tip = PointStamped()
        tip.header.stamp, tip.header.frame_id = stamp, self.frame_id
        tip.point.x, tip.point.y, tip.point.z = float(s.x_shovel), float(s.y_shovel), float(s.z_shovel)
        self.pub_tip.publish(tip)
        js = JointState()
        js.header.stamp = stamp
        js.name = ["boom", "bucket", *WHEELS]
        js.position = [float(s.phi_boom), float(s.phi_bucket)] + [float(a) for a in wheel_q]
        js.velocity = [float(s.dphi_boom), float(s.dphi_bucket)] + [float(w) for w in wheels]
        self.pub_js.publish(js)

    def _publish_markers(self) -> None:
        sim = self.sim
        with self.due.lock:
            surfaces = ss.pile_surfaces(sim.pile)
            boxes = ss.zone_boxes(sim.zones)
            trail = self.trail.array()
            fee = ss.fee_arrow(sim._site_xpos[sim.sid_tip].copy(), sim.last_fee.force)
        self.pub_markers.publish(marker_array(self.get_clock().now().to_msg(), self.frame_id, surfaces, boxes, trail,
                                              fee))

    def _publish_device_commands(self) -> None:
        log = self.due.command_log
        rows = []
        while log:
            wall, mono, f = log.popleft()      # atomic against the device thread's append
            rows += [wall, mono, float(f.wheel_setpoint), float(f.valve_boom), float(f.valve_bucket),
                     1.0 if f.enable else 0.0]
        if not rows:
            return
        m = Float64MultiArray(data=rows)
        m.layout.dim = [MultiArrayDimension(label="frames", size=len(rows) // 6, stride=len(rows)),
                        MultiArrayDimension(label="wall_s,mono_s,wheel_setpoint,valve_boom,valve_bucket,enable",
                                            size=6, stride=6)]
        self.pub_device_cmds.publish(m)

    # ------------------------------------------------------------------ sensors
    def _camera_info(self) -> CameraInfo:
        c = self.camera.camera_info()
        info = CameraInfo()
        info.header.frame_id = self.camera_frame_id
        info.width, info.height, info.distortion_model = c["width"], c["height"], c["distortion_model"]
        info.d, info.k, info.r, info.p = c["d"], c["k"], c["r"], c["p"]
        return info

    def _publish_image(self) -> None:
        pos, quat, _, stamp = self._state_and_stamp()   # the instant the machine was where the image shows it
        img = ss.camera_image(self.camera, pos, quat, self._rng_sensors)
        if img is None:
            self.camera_dropped += 1
            return
        self.marker_visible = self.camera.visible(pos, quat)
        m = Image()
        m.header.stamp, m.header.frame_id = stamp, self.camera_frame_id
        m.height, m.width = img.shape
        m.encoding, m.is_bigendian, m.step = "mono8", 0, img.shape[1]
        m.data = img.tobytes()
        self._info.header.stamp = stamp
        self.pub_info.publish(self._info)
        self.pub_img.publish(m)
        self.camera_frames += 1
        t_stamp = stamp.sec + 1e-9 * stamp.nanosec
        lag = (self._clock_offset_ns + time.monotonic() * 1e9) * 1e-9 - t_stamp   # on the stamps' clock
        self.pub_camera_lag.publish(Float64MultiArray(data=[t_stamp, lag]))

    def _publish_scan(self) -> None:
        with self.due.lock:
            occl = ss.machine_segments(self.sim.model, self.sim.data)
            ranges, amin, inc = ss.lidar_scan(self.lidar, self.sim.pile, self._rng_sensors, self.clutter, occl)
        m = LaserScan()
        m.header.stamp, m.header.frame_id = self.get_clock().now().to_msg(), self.lidar_frame_id
        f = self.lidar.laser_scan_fields()
        m.angle_min, m.angle_max, m.angle_increment = float(amin), float(f["angle_max"]), float(inc)
        m.range_min, m.range_max = float(f["range_min"]), float(f["range_max"])
        m.scan_time = float(self.scan_time)
        m.ranges = [float(r) for r in ranges]          # +inf: no return (REP 117), never NaN
        self.pub_scan.publish(m)
        self.scans += 1

    # ------------------------------------------------------------------ diagnostics
    def _diag_device(self):
        fw, due = self.due.firmware, self.due
        out = due.applied
        values = {"path": due.path, "commands": fw.commands, "heartbeats": fw.heartbeats, "watchdog_trips": fw.trips,
                  "watchdog_holds": fw.tripped, "estop": fw.estop, "drive_enabled": out.run,
                  "wheel_setpoint": out.wheel, "valve_boom": out.valve_boom, "valve_bucket": out.valve_bucket,
                  "sensor_frames": due.stats.sensor_frames, "load_cell_frames": due.stats.load_cell_frames,
                  "write_errors": due.stats.write_errors, **due.parser.counters()}
        if fw.estop:
            return WARN, "emergency stop pressed: machine held stopped", values
        if fw.command is None:
            return OK, "no command frame yet (bridge not connected)", values
        if fw.tripped:
            return WARN, "device watchdog holds the machine stopped (no command frame for 250 ms)", values
        return OK, "drive enabled" if out.run else "drive disabled (stop commanded)", values

    def _diag_realtime(self):
        st, w = self.due.stats, self._window
        now = time.monotonic()
        wall = max(now - w["t"], 1e-6)
        d_sim, d_over, d_resync = self.due.sim_time - w["sim"], st.overruns - w["overruns"], st.resyncs - w["resyncs"]
        d_busy, d_chunks = st.busy_s - w["busy"], st.chunks - w["chunks"]
        self._window = {"t": now, "sim": self.due.sim_time, "chunks": st.chunks, "overruns": st.overruns,
                        "resyncs": st.resyncs, "busy": st.busy_s}
        rtf = d_sim / wall
        values = {"real_time_factor": rtf, "overruns": st.overruns, "resyncs": st.resyncs,
                  "dropped_sim_s": st.dropped_s, "stepping_cpu_pct": 100.0 * d_busy / wall,
                  "mean_chunk_ms": 1000.0 * d_busy / d_chunks if d_chunks else 0.0,
                  "max_chunk_ms": 1000.0 * st.max_chunk_s, "sim_time_s": self.due.sim_time,
                  "lag_s": self.due.lag(now)}
        if d_over or d_resync:
            return WARN, (f"{d_over} chunk(s) of 20 ms simulated more than a chunk late, {d_resync} resync(s) in the "
                          f"last period (real-time factor {rtf:.2f})"), values
        return OK, f"real-time factor {rtf:.2f}", values

    def _diag_pile(self):
        values = {"pile": self.piles - 1, "slope_deg": self.pile_slope_deg, "material": self.sim.material,
                  "start_pose": self.start_pose, "resets": self.resets, "last_reset": self.reset_reason,
                  "attempt_state": self._attempt[0] if self._attempt else "none",
                  "attempt": self._attempt[1] if self._attempt else "none",
                  "reset_in_s": round(self._reset_at - time.monotonic(), 2) if self._reset_at else "none",
                  "loaded_mass_kg": round(float(self.sim.loaded_mass), 3)}
        return OK, f"pile {self.piles - 1}: {self.pile_slope_deg:.1f} deg {self.sim.material}", values

    def _diag_sensors(self):
        values = {"camera_frames": self.camera_frames, "camera_dropped": self.camera_dropped, "scans": self.scans,
                  "marker_in_view": self.marker_visible if self.marker_visible is not None else "unknown"}
        if self.camera is not None and self.marker_visible is False:
            return WARN, ("the ArUco marker is outside the simulated camera's view (camera_xyz / camera_rpy / "
                          "marker_to_base of machine_params against the machine's pose)"), values
        return OK, "sensors ok", values

    def shutdown(self) -> None:
        self.due.stop()


def main(args=None) -> int:
    # the device loop (a thread) shares the interpreter with the executor's callbacks: a 1 ms GIL
    # switch interval (default 5 ms) keeps its 10 ms sensor frames and 20 ms chunks on time while
    # a camera frame is being made
    sys.setswitchinterval(0.001)
    return run_node(TwinNode, "lhd_twin", args, before_destroy=lambda n: n.shutdown())


if __name__ == "__main__":
    raise SystemExit(main())
