"""The recorder node as a real process over DDS (issue 15 §5): an attempt armed -> running ->
success published by the test, with latched slope / zones / end zone published before the
recorder started, joint states, odometry, drift flags and commands at 10 Hz; the bag is read
back with rosbags (counts and values as published, latched topics in it, QoS of the publishers
in its metadata), its MCAP structure is checked by hand (test/mcap_check.py), and `lhd replay`
prints the metrics the test computes from what it published. Also: sqlite3 storage, a shutdown
in the middle of an attempt (a readable bag), an existing folder never overwritten, an
attempt that was over before the recorder started is not recorded, an unwritable run_dir."""
import json
import math
import os
import re
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.qos import qos_profile_sensor_data
from rclpy.serialization import deserialize_message
from rclpy.time import Time
from rosgraph_msgs.msg import Clock
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import JointState, Joy
from std_msgs.msg import Bool, Float64, Float64MultiArray

from lhd_loading_ros.cli import replay
from lhd_loading_ros.nodes.recorder_node import MessageTypes, _interface_file
from lhd_loading_ros.ros.qos import COMMAND_QOS, LATCHED_QOS, MEASUREMENT_QOS, STATUS_QOS

from mcap_check import read_summary
from rosutil import RosProcess, init_ros, shutdown_ros, spin_until

MODULE = "lhd_loading_ros.nodes.recorder_node"
TS = get_typestore(Stores.ROS2_JAZZY)
SLOPE = math.radians(22.0)
ZONES = [0.55, 0.95, 0.32, 1.62, -0.1, 1.0, 0.2, 0.4]
END_ZONE = ZONES[:3]
THETA = 0.05                       # base pitch (rad) carried by the odometry's quaternion
N = 20                             # control steps of the attempt
S = 1_000_000_000                  # ns per s
PROBE = ("import rclpy; from std_msgs.msg import Float64; rclpy.init(); n = rclpy.create_node('probe'); "
         "n.create_subscription(Float64, '/lhd/cmd', lambda m: None, 10); rclpy.spin(n)")


@pytest.fixture(scope="module")
def ros():
    init_ros()
    node = rclpy.create_node("test_recorder")
    yield node
    node.destroy_node()
    shutdown_ros()


def status(state, attempt, stamp_ns, **extra):
    st = DiagnosticStatus(name="lhd_supervisor/episode", message=state)
    vals = {"state": state, "episode": str(attempt), "controller": "rld", "stamp_ns": str(stamp_ns),
            "loaded_mass": "nan", "slope_deg": f"{math.degrees(SLOPE):.3f}", "material": "homogeneous",
            "reason": "", **extra}
    st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
    return st


def spin(node, seconds):
    spin_until(node, lambda: False, seconds)


class Rig:
    """The test's publishers (created before the recorder starts)."""

    def __init__(self, node, tag):
        self.node = node
        c = node.create_publisher
        self.slope = c(Float64, "/lhd/pile/slope", LATCHED_QOS)
        self.zones = c(Float64MultiArray, "/lhd/pile/zones", LATCHED_QOS)
        self.end_zone = c(Float64MultiArray, "/lhd/pile/end_zone", LATCHED_QOS)
        self.episode = c(DiagnosticStatus, "/lhd/episode", STATUS_QOS)
        self.joints = c(JointState, "/lhd/joint_states", MEASUREMENT_QOS)
        self.odom = c(Odometry, "/lhd/odom", qos_profile_sensor_data)      # best effort, as the ArUco node
        self.front = c(Bool, "/lhd/wheel_drift/front", MEASUREMENT_QOS)
        self.rear = c(Bool, "/lhd/wheel_drift/rear", MEASUREMENT_QOS)
        self.cmd = c(Float64MultiArray, "/lhd/cmd", COMMAND_QOS)
        self.joy = c(Joy, "/joy", 10)
        self.other = c(Float64, f"/other_{tag}/value", 10)                 # outside the prefix: not recorded
        self.pubs = [self.slope, self.zones, self.end_zone, self.joints, self.odom, self.front, self.rear, self.cmd,
                     self.joy]
        self.extra = []
        # a subscriber of another type on a recorded topic (a probe, a misconfigured node; another
        # process: DDS refuses two types on one topic in one): the topic is still recorded by its
        # publishers' type (until 2026-11-28 it left every bag: a review)
        self.probe = subprocess.Popen([sys.executable, "-c", PROBE], start_new_session=True)
        assert spin_until(node, lambda: any(i.topic_type == "std_msgs/msg/Float64"
                                            for i in node.get_subscriptions_info_by_topic("/lhd/cmd")), 60.0)

    def close(self):
        for p in self.pubs + [self.episode, self.other] + self.extra:
            self.node.destroy_publisher(p)
        self.probe.kill()
        self.probe.wait()

    def latched(self):
        self.slope.publish(Float64(data=SLOPE))
        self.zones.publish(Float64MultiArray(data=ZONES))
        self.end_zone.publish(Float64MultiArray(data=END_ZONE))

    def subscriptions(self, proc, pub) -> int:
        """Subscriptions of `proc`'s recorder (its node name) to `pub`'s topic: a recorder killed
        by an earlier test stays in the DDS graph until its lease runs out, under the default name."""
        name = getattr(proc, "node_name", "lhd_recorder")
        return sum(1 for i in self.node.get_subscriptions_info_by_topic(pub.topic_name) if i.node_name == name)

    def wait_recorder_subscribed(self, proc, timeout=20.0):
        """The recorder subscribes to every topic once a bag is open; then DDS matches it."""
        ok = spin_until(self.node, lambda: all(self.subscriptions(proc, p) >= 1 and p.get_subscription_count() >= 1
                                               for p in self.pubs)
                        and self.subscriptions(proc, self.episode) >= 2, timeout)
        assert ok, ([(p.topic_name, p.get_subscription_count()) for p in self.pubs], proc.log())
        spin(self.node, 0.3)

    def run_attempt(self, proc, attempt, steps, rear_from=None):
        """Attempt `attempt` armed (once the recorder listens), running, then `steps` control
        periods of 0.1 s: joints, odometry, drift flags (rear from step `rear_from`), a command
        [1, 0, 0.1 k] 40 ms into each."""
        node, clock = self.node, self.node.get_clock()
        assert spin_until(node, lambda: self.subscriptions(proc, self.episode) >= 1
                          and self.episode.get_subscription_count() >= 1, 30.0), proc.log()
        self.episode.publish(status("armed", attempt, clock.now().nanoseconds))
        self.wait_recorder_subscribed(proc)
        self.episode.publish(status("running", attempt, clock.now().nanoseconds))
        spin(node, 0.1)
        for k in range(steps):
            self.state(k, 0.0, 0.01 * k, False, rear_from is not None and k >= rear_from)
            spin(node, 0.04)
            self.cmd.publish(Float64MultiArray(data=[1.0, 0.0, 0.1 * k]))
            spin(node, 0.06)

    def state(self, k, boom, bucket, front, rear, x0=-0.3):
        js = JointState(name=["boom", "bucket", "wheels"], position=[boom, bucket, 0.0], velocity=[0.0, 0.0, 2.5])
        self.joints.publish(js)
        od = Odometry()
        od.header.frame_id = "pile"
        od.pose.pose.position.x, od.pose.pose.position.z = x0 + 0.02 * k, 0.137
        od.pose.pose.orientation.w, od.pose.pose.orientation.y = math.cos(THETA / 2), math.sin(THETA / 2)
        od.twist.twist.linear.x = 0.2
        self.odom.publish(od)
        self.front.publish(Bool(data=front))
        self.rear.publish(Bool(data=rear))


def start_recorder(tmp_path, run_dir, name="recorder", node_name=None, **params):
    proc = RosProcess(MODULE, {"run_dir": str(run_dir), **params}, tmp_path / f"{name}.log",
                      remaps={"__node": node_name} if node_name else None)
    proc.node_name = node_name or "lhd_recorder"
    return proc


def wait_file(path: Path, proc, timeout=15.0):
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end and not path.exists():
        time.sleep(0.05)
    assert path.exists(), (path, proc.log())


def read_back(bag: Path) -> dict:
    """topic -> [(timestamp, message)] read with rosbags' Reader and the Jazzy typestore."""
    out = {}
    with Reader(bag) as r:
        for conn, t, raw in r.messages():
            out.setdefault(conn.topic, []).append((t, TS.deserialize_cdr(raw, conn.msgtype)))
    return out


def test_an_attempt_is_recorded_and_replayed(ros, tmp_path, capsys):
    rig = Rig(ros, "a")
    rig.latched()
    # an attempt that was over before the recorder started: its statuses reach the recorder only
    # as the latched history of /lhd/episode, and must not open a bag
    clock = ros.get_clock()
    for st in ("armed", "running", "timeout"):
        rig.episode.publish(status(st, 6, clock.now().nanoseconds))
    run_dir = tmp_path / "run"
    t_begin = clock.now().nanoseconds
    proc = start_recorder(tmp_path, run_dir, post_roll_s=0.5)
    diags = []
    diag_sub = ros.create_subscription(DiagnosticArray, "/diagnostics",
                                       lambda m: diags.extend(s for s in m.status if "lhd_recorder: recording" in s.name), 50)
    try:
        assert spin_until(ros, lambda: rig.episode.get_subscription_count() >= 1, 30.0), proc.log()
        spin(ros, 1.0)
        assert not any((run_dir / "bags").iterdir()), "a bag was opened for attempt 6, which was over"

        rig.episode.publish(status("armed", 7, clock.now().nanoseconds))
        rig.wait_recorder_subscribed(proc)
        t_run = clock.now().nanoseconds
        rig.episode.publish(status("running", 7, t_run))
        spin(ros, 0.1)
        cmds, fronts, rears, late_sent, late = [], [], [], [], None
        for k in range(N):
            front, rear = 3 <= k <= 7, k % 4 != 3
            rig.state(k, -0.02 * k, 0.03 * k, front, rear)
            fronts.append(front)
            rears.append(rear)
            if k == 5:      # a topic that appears during the attempt is recorded from its discovery on
                late = ros.create_publisher(Float64, "/lhd/late_topic", 10)
                rig.extra.append(late)
            if late is not None:
                late.publish(Float64(data=float(k)))
                late_sent.append(float(k))
            if 10 <= k < 15:
                rig.joy.publish(Joy(axes=[0.1 * k, 0.0], buttons=[1, 0]))
            rig.other.publish(Float64(data=1.0))
            spin(ros, 0.04)
            u = [round(0.1 * k, 3), -0.05 * (k % 3), 0.02 * k - 0.2]
            rig.cmd.publish(Float64MultiArray(data=u))
            cmds.append(u)
            spin(ros, 0.06)
        t_end = clock.now().nanoseconds
        elapsed = (t_end - t_run) / 1e9
        rig.episode.publish(status("success", 7, t_end, reason="bucket tip reached the end zone",
                                   elapsed_s=f"{elapsed:.2f}", front_drift_pct="25.00", rear_drift_pct="75.00",
                                   phi_final_deg="12.00"))
        spin(ros, 0.05)
        rig.cmd.publish(Float64MultiArray(data=[0.0, 0.0, 0.0]))     # the stop
        for k in range(3):      # the machine after the end: in the bag, not in the final pitch
            rig.state(N + k, -0.5, 1.2, True, True)
            spin(ros, 0.1)
        assert spin_until(ros, lambda: any("recording attempt 7 into" in s.message for s in diags), 5.0), diags[-3:]
        bag = run_dir / "bags" / "attempt_0007"
        wait_file(bag / "metadata.yaml", proc)
    finally:
        rc = proc.stop()
        rig.close()
        ros.destroy_subscription(diag_sub)
    assert rc == 0, proc.log()
    t_finish = clock.now().nanoseconds
    assert sorted(p.name for p in (run_dir / "bags").iterdir()) == ["attempt_0007"]

    # ---- read back with rosbags
    got = read_back(bag)
    assert "/other_a/value" not in got
    # float64 through CDR is bit-exact
    assert [list(m.data) for _, m in got["/lhd/cmd"]] == cmds + [[0.0, 0.0, 0.0]]
    assert len(got["/lhd/joint_states"]) == len(got["/lhd/odom"]) == N + 3
    assert [list(m.position[:2]) for _, m in got["/lhd/joint_states"][:N]] == [[-0.02 * k, 0.03 * k] for k in range(N)]
    assert [m.data for _, m in got["/lhd/wheel_drift/front"][:N]] == fronts
    assert [m.data for _, m in got["/lhd/wheel_drift/rear"][:N]] == rears
    # the latched topics, published before the recorder started
    assert [m.data for _, m in got["/lhd/pile/slope"]] == [SLOPE]
    assert [list(m.data) for _, m in got["/lhd/pile/zones"]] == [ZONES]
    assert [list(m.data) for _, m in got["/lhd/pile/end_zone"]] == [END_ZONE]
    # the status history (attempt 6, then 7) and the live statuses of attempt 7
    states = [(dict((kv.key, kv.value) for kv in m.values)["episode"], m.message) for _, m in got["/lhd/episode"]]
    assert states == [("6", "armed"), ("6", "running"), ("6", "timeout"), ("7", "armed"), ("7", "running"),
                      ("7", "success")]
    assert [m.axes[0] for _, m in got["/joy"]] == pytest.approx([0.1 * k for k in range(10, 15)])
    late_got = [m.data for _, m in got["/lhd/late_topic"]]
    assert len(late_got) >= 5 and late_got == late_sent[-len(late_got):], (late_got, late_sent)
    assert any("lhd_recorder" in s.name for _, m in got["/diagnostics"] for s in m.status)
    # receive times: ROS time (system time here), in order, inside the test's window
    for topic, msgs in got.items():
        ts = [t for t, _ in msgs]
        assert ts == sorted(ts) and t_begin <= ts[0] and ts[-1] <= t_finish, topic

    # ---- metadata: rosbag2 version 9, the publishers' QoS, the attempt
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    assert meta["custom_data"]["lhd.attempt"] == "7" and meta["custom_data"]["lhd.closed_by"] == "post-roll after success"
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"] for t in meta["topics_with_message_count"]}
    assert [q["durability"] for q in qos["/lhd/pile/slope"]] == ["transient_local"]
    assert [q["reliability"] for q in qos["/lhd/odom"]] == ["best_effort"]
    assert [(q["reliability"], q["durability"]) for q in qos["/lhd/cmd"]] == [("reliable", "volatile")]

    # ---- the MCAP file itself, read by hand from the specification
    files = list(bag.glob("*.mcap"))
    assert len(files) == 1
    summ = read_summary(files[0])
    assert summ["profile"] == "ros2"
    topics = {c["topic"]: c for c in summ["channels"].values()}
    assert set(topics) == set(got)
    for c in topics.values():
        sch = summ["schemas"][c["schema_id"]]
        assert c["encoding"] == "cdr" and sch["encoding"] == "ros2msg" and "offered_qos_profiles" in c["metadata"]
    sch = summ["schemas"][topics["/lhd/pile/slope"]["schema_id"]]
    assert (sch["name"], sch["encoding"], sch["data"].strip()) == ("std_msgs/msg/Float64", "ros2msg", "float64 data")
    assert "float64[] data" in summ["schemas"][topics["/lhd/cmd"]["schema_id"]]["data"]
    assert summ["statistics"]["message_count"] == sum(len(v) for v in got.values())
    assert {summ["channels"][cid]["topic"]: n for cid, n in summ["statistics"]["per_channel"].items()} == \
        {t: len(v) for t, v in got.items()}

    # ---- lhd replay: the metrics the test computes from what it published
    png = tmp_path / "attempt7.png"
    assert replay.main([str(bag), "--json", "--plot", str(png)]) == 0
    m = json.loads(capsys.readouterr().out)
    assert (m["attempt"], m["outcome"], m["reason"]) == (7, "success", "bucket tip reached the end zone")
    assert m["elapsed_s"] == pytest.approx(elapsed, abs=1e-9)
    assert m["front_drift_pct"] == pytest.approx(100.0 * sum(fronts) / N)      # 5 of 20 steps: 25 %
    assert m["rear_drift_pct"] == pytest.approx(100.0 * sum(rears) / N)        # 15 of 20: 75 %
    # pitch of the tip frame = bucket - boom - base pitch (all rotations about y), last state before the end
    assert m["final_pitch_deg"] == pytest.approx(math.degrees(0.03 * (N - 1) + 0.02 * (N - 1) - THETA), abs=1e-6)
    assert m["final_pitch_reported_deg"] == 12.0           # what the status said, shown apart
    c = m["commands"]
    assert c["count"] == N
    assert c["max_abs"] == pytest.approx([max(abs(u[i]) for u in cmds) for i in range(3)])
    assert 0.0 < c["first_zero_after_end_ms"] < 300.0
    assert m["pile"]["slope_deg"] == pytest.approx(22.0) and m["pile"]["end_zone"] == END_ZONE
    assert m["tip"]["samples_in_attempt"] == N and m["missing"] == []
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    assert replay.main([str(bag)]) == 0
    text = capsys.readouterr().out
    assert f"{elapsed:.2f}" in text and "25.00" in text and "75.00" in text and "attempt 7: success" in text


def test_sqlite3_an_existing_folder_and_a_shutdown_during_the_attempt(ros, tmp_path, capsys):
    """storage sqlite3; attempt 3's folder exists already (a restarted supervisor reused the
    number): kept untouched, the bag goes to attempt_0003_2; the recorder stopped (SIGINT)
    while the attempt runs closes a readable bag; with use_sim_time the stamps are sim time."""
    rig = Rig(ros, "b")
    rig.latched()
    run_dir = tmp_path / "run"
    old = run_dir / "bags" / "attempt_0003"
    old.mkdir(parents=True)
    (old / "marker.txt").write_text("earlier attempt 3")
    sim0, wall0 = 5000 * S, time.monotonic()      # a sim clock at 5000 s, advancing with the wall clock
    pub_clock = ros.create_publisher(Clock, "/clock", 10)
    clock_timer = ros.create_timer(0.02, lambda: pub_clock.publish(
        Clock(clock=Time(nanoseconds=sim0 + int((time.monotonic() - wall0) * S)).to_msg())))
    proc = start_recorder(tmp_path, run_dir, name="recorder_sqlite", storage="sqlite3", use_sim_time="true")
    try:
        rig.run_attempt(proc, 3, 8, rear_from=4)
        spin(ros, 0.2)
    finally:
        rc = proc.stop()
        rig.close()
        ros.destroy_timer(clock_timer)
        ros.destroy_publisher(pub_clock)
    sim_end = sim0 + int((time.monotonic() - wall0) * S)
    assert rc == 0, proc.log()
    assert "attempt_0003 already exists" in proc.log()
    assert sorted(os.listdir(old)) == ["marker.txt"] and (old / "marker.txt").read_text() == "earlier attempt 3"
    bag = run_dir / "bags" / "attempt_0003_2"
    assert (bag / "metadata.yaml").is_file() and len(list(bag.glob("*.db3"))) == 1
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "sqlite3" and meta["custom_data"]["lhd.closed_by"] == "shutdown"
    assert "attempt_0003_2" in meta["custom_data"]["lhd.note"]
    got = read_back(bag)
    assert [list(m.data) for _, m in got["/lhd/cmd"]] == [[1.0, 0.0, 0.1 * k] for k in range(8)]
    stamps = [t for msgs in got.values() for t, _ in msgs]
    assert sim0 < min(stamps) and max(stamps) <= sim_end, (min(stamps) - sim0, sim_end - max(stamps))
    # the sqlite3 file read without rosbags: rosbag2's schema version 4 (Jazzy), the CDR decoded by rclpy
    db = sqlite3.connect(next(bag.glob("*.db3")))
    try:
        assert db.execute("SELECT schema_version FROM schema").fetchone()[0] == 4
        topic_id = db.execute("SELECT id FROM topics WHERE name = '/lhd/cmd'").fetchone()[0]
        written = [r[0] for r in db.execute("SELECT timestamp FROM messages ORDER BY id")]
        assert written == sorted(written)          # on the sim clock too, the log time never goes back
        rows = db.execute("SELECT data FROM messages WHERE topic_id = ? ORDER BY timestamp", (topic_id,)).fetchall()
        assert [list(deserialize_message(r[0], Float64MultiArray).data) for r in rows] == \
            [[1.0, 0.0, 0.1 * k] for k in range(8)]
        defs = dict(db.execute("SELECT topic_type, encoding FROM message_definitions"))
        assert defs["std_msgs/msg/Float64MultiArray"] == "ros2msg"
    finally:
        db.close()
    assert [m.data for _, m in got["/lhd/wheel_drift/rear"]] == [k >= 4 for k in range(8)]
    assert [m.data for _, m in got["/lhd/pile/slope"]] == [SLOPE]
    # replay: no end in the bag, said plainly; the figures up to the last message
    assert replay.main([str(bag)]) == 0
    text = capsys.readouterr().out
    assert "attempt 3: running" in text and "no end status of attempt 3" in text
    assert "commands during the attempt: 8" in text
    assert re.search(r"rear drift \(%\) +50\.00 +-\n", text) and "drift sampled at 8 command(s)" in text


def test_log_times_on_the_sim_clock_never_go_back_within_a_bag(monkeypatch):
    """A review (2026-11-30): with use_sim_time the log time was the sim clock's now minus the wall-clock
    wait in the executor; the sim clock jumps between callbacks (and in lockstep runs faster than the
    wall clock), so a message that waited long came out earlier than the one written before it, and a
    bag's end status was logged before its running statuses. The sequence below is that case: message
    B arrived early, waited 16 ms, and was taken after A at the same sim time."""
    from types import SimpleNamespace

    from lhd_loading_ros.nodes import recorder_node
    from lhd_loading_ros.nodes.recorder_node import RecorderNode

    sim_now = {"ns": 0}
    node = SimpleNamespace(_last_sim_ns=0, _sim_time_active=lambda: True,
                           get_clock=lambda: SimpleNamespace(now=lambda: SimpleNamespace(nanoseconds=sim_now["ns"])))
    wall = {"ns": 0}
    monkeypatch.setattr(recorder_node.time, "time_ns", lambda: wall["ns"])
    ms = 1_000_000
    out = []
    for sim_ns, wall_ns, received_ns in ((20 * ms, 21 * ms, 20 * ms),     # A: taken at once
                                         (20 * ms, 21 * ms, 5 * ms),      # B: arrived 16 ms before it was taken
                                         (40 * ms, 41 * ms, 40 * ms)):
        sim_now["ns"], wall["ns"] = sim_ns, wall_ns
        out.append(RecorderNode.receive_time(node, {"received_timestamp": received_ns}))
    assert out == [19 * ms, 19 * ms, 39 * ms]          # B at A's time, not 4 ms: never back
    node._sim_time_active = lambda: False              # on the system clock: DDS's arrival stamp as it is
    assert RecorderNode.receive_time(node, {"received_timestamp": 5 * ms}) == 5 * ms


@pytest.mark.parametrize("storage, ext", [("mcap", "mcap"), ("sqlite3", "db3")])
def test_a_recorder_killed_mid_attempt_leaves_a_bag_that_lhd_bag_recover_reads(ros, tmp_path, capsys, storage, ext):
    """SIGKILL gives the recorder no close: no metadata.yaml, no MCAP summary. It flushes the open
    bag every flush_period_s (here 0.3 s; sqlite3: commits), so `lhd bag recover` rewrites what was
    flushed as a complete bag of the same storage, which `lhd replay` reads: every command published
    more than a flush period and a margin before the kill is in it, with its values. Until
    2026-11-28 such an MCAP bag was a 0-byte file (rosbags keeps a 1 MiB chunk in memory; a review's
    fault injection), and a sqlite3 one was left to `ros2 bag reindex`, which this machine lacks."""
    import signal

    from lhd_loading_ros.cli.bag import main as bag_main

    rig = Rig(ros, "c")
    rig.latched()
    run_dir = tmp_path / "run"
    proc = start_recorder(tmp_path, run_dir, name=f"recorder_killed_{storage}", flush_period_s=0.3, storage=storage,
                          node_name=f"lhd_recorder_killed_{storage}")    # told apart from the one killed before
    try:
        rig.run_attempt(proc, 4, 12)
        spin(ros, 1.0)                             # > 3 flush periods after the last command
        os.killpg(proc.proc.pid, signal.SIGKILL)
        proc.proc.wait(10)
    finally:
        proc.stop()
        rig.close()
    bag = run_dir / "bags" / "attempt_0004"
    original = next(bag.glob(f"*.{ext}"))
    before = {p.name: p.read_bytes() for p in bag.iterdir()}       # sqlite3: and its hot journal
    assert not (bag / "metadata.yaml").exists() and len(before[original.name]) > 0
    assert replay.main([str(bag)]) != 0
    assert f"lhd bag recover {bag}" in capsys.readouterr().err
    assert bag_main(["recover", str(bag)]) == 0
    out = bag.with_name("attempt_0004_recovered")
    assert str(out) in capsys.readouterr().out
    got = read_back(out)
    assert [p.suffix for p in out.iterdir() if p.name != "metadata.yaml"] == [f".{ext}"]
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before            # the original untouched
    assert [list(m.data) for _, m in got["/lhd/cmd"]] == [[1.0, 0.0, 0.1 * k] for k in range(12)]
    assert [m.data for _, m in got["/lhd/pile/slope"]] == [SLOPE]
    assert len(got["/lhd/joint_states"]) == 12
    assert replay.main([str(out)]) == 0
    assert "attempt 4: running" in capsys.readouterr().out
    assert bag_main(["recover", str(bag)]) == 1                 # nothing is overwritten
    assert "exists" in capsys.readouterr().err
    assert sorted(p.name for p in bag.parent.iterdir()) == ["attempt_0004", "attempt_0004_recovered"]  # no copy left
    assert bag_main(["recover", str(bag), "--out", str(tmp_path / "no_such" / "x")]) == 1
    assert "no_such: no such folder for --out" in capsys.readouterr().err


def test_a_run_dir_that_cannot_be_written_ends_the_node_with_status_2(tmp_path):
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("a file where the run folder should be")
    proc = start_recorder(tmp_path, blocker / "run", name="recorder_bad")
    try:
        proc.proc.wait(60)
    finally:
        rc = proc.stop()
    assert rc == 2, proc.log()
    assert "run_dir" in proc.log() and "cannot be written" in proc.log() and "Traceback" not in proc.log()


def test_message_definitions_agree_with_the_installed_interfaces():
    """The schemas written into a bag: rosbags' Jazzy typestore, and the fallback for types it
    does not know (built from the installed .msg files, with their dependencies) gives the
    same definition and the installed type hash (share/<pkg>/msg/<Name>.json)."""
    types = MessageTypes()
    for t in ("nav_msgs/msg/Odometry", "diagnostic_msgs/msg/DiagnosticArray", "sensor_msgs/msg/Joy",
              "std_msgs/msg/Float64MultiArray", "sensor_msgs/msg/JointState"):
        installed = json.loads(_interface_file(t, ".json").read_text())["type_hashes"][0]
        assert installed["type_name"] == t
        msgdef, rihs = types.definition(t)
        assert rihs == installed["hash_string"]
        assert types._from_installed(t, installed["hash_string"]) == (msgdef, rihs)
    with pytest.raises(ValueError, match="no definition of lhd_msgs/msg/Nothing"):
        types.definition("lhd_msgs/msg/Nothing")
    with pytest.raises(ValueError, match="expected package/msg/Name"):
        types.definition("Float64")


def test_the_parameter_file_is_what_the_node_takes(ros, tmp_path):
    """config/recorder_node.yaml: every key a parameter of the node, accepted as written."""
    from rclpy.parameter import Parameter

    from lhd_loading_ros.nodes.recorder_node import RecorderNode

    path = Path(__file__).resolve().parents[2] / "config" / "recorder_node.yaml"
    from lhd_loading_ros.ros.params_file import params_of

    values = params_of(yaml.safe_load(path.read_text()), "/lhd_recorder")
    overrides = [Parameter(k, value=v) for k, v in values.items()] + [Parameter("run_dir", value=str(tmp_path / "r"))]
    node = RecorderNode(context=ros.context, parameter_overrides=overrides)
    try:
        assert {k: node.p[k] for k in values} == values
        assert node.extra == ("/joy", "/diagnostics") and node.prefix == "/lhd"
        assert (tmp_path / "r" / "bags").is_dir() and not any((tmp_path / "r" / "bags").iterdir())
    finally:
        node.destroy_node()
