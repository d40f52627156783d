"""The hardware side of the machine as the supervisor hears it, faked by a test: joint states,
odometry, drift flags, the bridge's status (and optionally the load cell) at 50 Hz from a pose
(base x, boom, bucket), latched pile slope / zones / e-stop publishers (the slope repeated at 5 Hz
once published, as the LiDAR slope node sends one per scan), the supervisor's arm and abort services,
and its /lhd/episode statuses, spun in a background thread (test_supervisor_node.py)."""
import threading
import time

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray
from std_srvs.srv import Trigger

REL = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
STATUS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL)
R_WHEEL = 0.137          # m, config machine.wheel_radius


class _Repeating:
    """A publisher whose latest message `repeat` sends again (the LiDAR node's one slope per scan)."""

    def __init__(self, pub):
        self.pub, self.last = pub, None

    def publish(self, msg):
        self.last = msg
        self.pub.publish(msg)

    def repeat(self):
        if self.last is not None:
            self.pub.publish(self.last)


class FakeMachine:
    """A 50 Hz feeder from `pose` and the supervisor's outputs; `feed` switches each input off."""

    def __init__(self, node, pose, front=False, rear=False):
        self.node = node
        self.pose = pose                   # (base x, boom, bucket)
        self.feed = {"joints": True, "odom": True, "drift": True, "hw": True, "slope": True}
        self.front, self.rear = front, rear
        self.load_cell = None              # kg to publish on /lhd/load_cell/mass at 50 Hz, or None
        self.command_stale = False         # the bridge's own command watchdog, in its hw/status
        self.imu = None                    # (w, x, y, z) to publish on /lhd/imu at 50 Hz, or None
        self.pose_published_at = {}        # pose -> first publish time (monotonic)
        self.last_joints_at = None
        self.statuses = []                 # (arrival, {key: value})
        self.pub_js = node.create_publisher(JointState, "/lhd/joint_states", REL)
        self.pub_odom = node.create_publisher(Odometry, "/lhd/odom", REL)
        self.pub_front = node.create_publisher(Bool, "/lhd/wheel_drift/front", REL)
        self.pub_rear = node.create_publisher(Bool, "/lhd/wheel_drift/rear", REL)
        self.pub_hw = node.create_publisher(DiagnosticStatus, "/lhd/hw/status", REL)
        self.pub_slope = _Repeating(node.create_publisher(Float64, "/lhd/pile/slope", LATCHED))
        self._ticks = 0
        self.pub_zones = node.create_publisher(Float64MultiArray, "/lhd/pile/zones", LATCHED)
        self.pub_estop = node.create_publisher(Bool, "/lhd/estop", LATCHED)
        self.pub_cell = node.create_publisher(Float64, "/lhd/load_cell/mass", REL)
        self.pub_imu = node.create_publisher(Imu, "/lhd/imu", REL)
        node.create_subscription(DiagnosticStatus, "/lhd/episode", self._on_status, STATUS)
        self.arm_client = node.create_client(Trigger, "/lhd/arm")
        self.abort_client = node.create_client(Trigger, "/lhd/abort")
        node.create_timer(0.02, self._tick)
        self.executor = SingleThreadedExecutor(context=node.context)
        self.executor.add_node(node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_status(self, msg):
        self.statuses.append((time.monotonic(), {k.key: k.value for k in msg.values}))

    def _tick(self):
        self._ticks += 1
        if self.feed["slope"] and self._ticks % 10 == 0:
            self.pub_slope.repeat()
        base_x, boom, bucket = self.pose
        stamp = self.node.get_clock().now().to_msg()
        if self.feed["odom"]:
            o = Odometry()
            o.header.stamp = stamp
            o.pose.pose.position.x, o.pose.pose.position.z = base_x, R_WHEEL
            o.pose.pose.orientation.w = 1.0
            self.pub_odom.publish(o)
        if self.feed["joints"]:
            js = JointState()
            js.header.stamp = stamp
            js.name = ["boom", "bucket", "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"]
            js.position = [boom, bucket, 0.0, 0.0, 0.0, 0.0]
            js.velocity = [0.0] * 6
            self.pub_js.publish(js)
            self.last_joints_at = time.monotonic()
            self.pose_published_at.setdefault(self.pose, self.last_joints_at)
        if self.feed["drift"]:
            self.pub_front.publish(Bool(data=self.front))
            self.pub_rear.publish(Bool(data=self.rear))
        if self.load_cell is not None:
            self.pub_cell.publish(Float64(data=self.load_cell))
        if self.imu is not None:
            m = Imu()
            m.header.stamp = stamp
            m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z = self.imu
            self.pub_imu.publish(m)
        if self.feed["hw"]:
            st = DiagnosticStatus(level=DiagnosticStatus.OK, name="/lhd_bridge: device", message="drive enabled")
            st.values = [KeyValue(key="estop", value="False"),
                         KeyValue(key="command_stale", value=str(self.command_stale))]
            self.pub_hw.publish(st)

    def set_pose(self, pose):
        self.pose_published_at.pop(pose, None)
        self.pose = pose

    def call(self, client, timeout=20.0):
        assert client.wait_for_service(timeout_sec=timeout), "no supervisor service"
        fut = client.call_async(Trigger.Request())
        assert wait_for(fut.done, timeout)
        return fut.result()

    def state(self):
        return self.statuses[-1][1] if self.statuses else {}

    def wait_state(self, state, episode=None, timeout=10.0, since=0):
        """The first status from index `since` on with this state (and attempt number)."""
        found = []

        def pred():
            for t, kv in self.statuses[since:]:
                if kv.get("state") == state and (episode is None or kv.get("episode") == str(episode)):
                    found.append((t, kv))
                    return True
            return False

        assert wait_for(pred, timeout), f"no '{state}' status; last: {self.state()}"
        return found[0]

    def close(self):
        self.executor.shutdown()
        self.thread.join(5.0)



def wait_for(pred, timeout, step=0.005):
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if pred():
            return True
        time.sleep(step)
    return pred()


SUPERVISOR = "lhd_loading_ros.nodes.supervisor_node"


def supervisor_rig(tmp_path_factory, name: str, params: dict, pose, slope_deg: float | None = 20.0, zones=None):
    """A FakeMachine at `pose` in a new node `name`, and a supervisor process with `params` (its
    run_dir a fresh folder, `r.run_dir`; its log `<name>.log` beside it); the pile's slope and
    zones published when given. Close with `close_rig`."""
    import math

    import rclpy

    from rosutil import RosProcess, init_ros

    init_ros()
    node = rclpy.create_node(name)
    r = FakeMachine(node, pose)
    r.run_dir = tmp_path_factory.mktemp(f"run_{name}")
    r.proc = RosProcess(SUPERVISOR, {"run_dir": str(r.run_dir), **params}, r.run_dir.parent / f"{name}.log")
    if slope_deg is not None:
        r.pub_slope.publish(Float64(data=math.radians(slope_deg)))
    if zones is not None:
        r.pub_zones.publish(Float64MultiArray(data=zones))
    return r


def close_rig(r) -> None:
    from rosutil import shutdown_ros

    r.proc.stop()
    r.close()
    r.node.destroy_node()
    shutdown_ros()
