"""docs/serial_protocol.md is the truth: a second implementation written from it alone
(doc_protocol.py, which reads the field tables from the document) interoperates with
protocol.py byte for byte, with the bridge node as a real process over a real pseudo-terminal
(both directions, sequence numbers per frame type, gaps and lost frames counted exactly as the
document says), and with the reference firmware compiled on this host."""
import os
import shutil
import subprocess
import threading
import time
import tty
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from hypothesis import given, settings
from hypothesis import strategies as st
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

import doc_protocol as doc
from lhd_hw_bridge import protocol
from rosutil import RosProcess, init_ros, shutdown_ros, spin_until

LAYOUTS = doc.read_layouts()
SENSOR, COMMAND, HEARTBEAT, LOAD_CELL = 0x01, 0x02, 0x03, 0x04   # the document's type codes
FIRMWARE = Path(__file__).resolve().parents[2] / "lhd_hw_bridge/lhd_hw_bridge/firmware/lhd_due/lhd_due.ino"


@pytest.fixture(scope="module")
def ros():
    init_ros()
    yield
    shutdown_ros()


# ---------------------------------------------------------------- byte for byte with protocol.py
def test_document_tables_and_check_value():
    assert doc.crc16_ccitt_false(b"123456789") == 0x29B1           # the check value the document gives
    assert {c: (lay.name, lay.size) for c, lay in LAYOUTS.items()} == {
        SENSOR: ("sensor", 27), COMMAND: ("command", 5), HEARTBEAT: ("heartbeat", 4), LOAD_CELL: ("load_cell", 13)}


i16 = st.integers(-32768, 32767)
u16 = st.integers(0, 65535)
tri = st.sampled_from([-1, 0, 1])


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(i16, min_size=7, max_size=7), st.lists(u16, min_size=3, max_size=3),
       tri, tri, st.integers(0, 255), st.integers(0, 255))
def test_sensor_frames_are_the_same_bytes_both_ways(t, angles_wheels, currents, vb, vk, flags, seq):
    s = [1e-4, 1e-4, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3]
    names = ["boom_angle", "bucket_angle", "boom_rate", "bucket_rate", "wheel_fl", "wheel_fr", "wheel_rear"]
    values = {"device_time": t, **{n: r * k for n, r, k in zip(names, angles_wheels, s)},
              "current_fl": currents[0] * 1e-3, "current_fr": currents[1] * 1e-3, "current_rear": currents[2] * 1e-3,
              "valve_boom": vb, "valve_bucket": vk, "flags": flags}
    ours = doc.raw_frame(SENSOR, seq, LAYOUTS[SENSOR].pack(values))
    frame = protocol.SensorFrame(t, *(values[n] for n in names), values["current_fl"], values["current_fr"],
                                 values["current_rear"], vb, vk, flags)
    assert protocol.encode(frame, seq) == ours
    (got_seq, got), = protocol.FrameParser().feed(ours)
    assert got_seq == seq and got == protocol.decode_packet(protocol.cobs_decode(ours[:-1]))[1]
    rx = doc.Receiver(LAYOUTS, {"sensor"})
    (_, _, back), = rx.feed(protocol.encode(frame, seq))
    assert back == pytest.approx(values, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(i16, tri, tri, st.integers(0, 1), st.integers(0, 2**32 - 1), st.integers(0, 255))
def test_command_and_heartbeat_frames_are_the_same_bytes_both_ways(w, vb, vk, en, host_ms, seq):
    cmd = {"wheel_setpoint": w * 1e-3, "valve_boom": vb, "valve_bucket": vk, "enable": en}
    assert protocol.encode(protocol.CommandFrame(w * 1e-3, vb, vk, bool(en)), seq) == \
        doc.raw_frame(COMMAND, seq, LAYOUTS[COMMAND].pack(cmd))
    assert protocol.encode(protocol.HeartbeatFrame(host_ms), seq) == \
        doc.raw_frame(HEARTBEAT, seq, LAYOUTS[HEARTBEAT].pack({"host_time": host_ms}))


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(-2**31, 2**31 - 1), st.integers(-2**23, 2**23 - 1),
       st.integers(0, 255), st.integers(0, 255))
def test_load_cell_frames_are_the_same_bytes_both_ways(t, grams, raw, flags, seq):
    values = {"device_time": t, "mass": grams * 1e-3, "raw": raw, "flags": flags}
    ours = doc.raw_frame(LOAD_CELL, seq, LAYOUTS[LOAD_CELL].pack(values))
    assert protocol.encode(protocol.LoadCellFrame(t, grams / 1000.0, raw, flags), seq) == ours
    (got_seq, got), = protocol.FrameParser().feed(ours)
    assert got_seq == seq and (got.device_time_us, round(got.mass * 1000), got.raw, got.flags) == (t, grams, raw, flags)
    (_, _, back), = doc.Receiver(LAYOUTS, {"load_cell"}).feed(ours)
    assert back == pytest.approx(values, abs=1e-9)


def test_document_range_of_raw_counts_is_the_one_protocol_py_checks():
    """A raw value one past 24 bits, either way: both receivers drop it as a framing error."""
    rx = doc.Receiver(LAYOUTS, {"load_cell"})
    p = protocol.FrameParser()
    for k, raw in enumerate((2**23, -2**23 - 1, 2**23 - 1, -2**23)):
        wire = doc.raw_frame(LOAD_CELL, k, doc.struct.pack("<IiiB", 0, 0, raw, 0))
        rx.feed(wire)
        p.feed(wire)
    assert rx.counts["framing_errors"] == p.framing_errors == 2 and rx.counts["frames"] == p.frames == 2


def test_protocol_py_counts_gaps_per_type_as_the_document_says():
    """The same stream through both receivers: identical counters, gaps per type, drops exact."""
    tx = doc.Sender(LAYOUTS)
    cmd = {"wheel_setpoint": 1.0, "valve_boom": 1, "valve_bucket": 0, "enable": 1}
    stream = b""
    for i in range(600):                                    # wraps 255 -> 0 twice
        frame = tx.frame("command", cmd)
        if i % 50 == 0:
            stream += tx.frame("heartbeat", {"host_time": i})   # its own counter: no gap in commands
        if i in (10, 300, 301, 302):                        # lost: 2 gaps, 4 frames
            continue
        if i == 400:                                        # corrupted: dropped, then 1 gap, 1 lost frame
            frame = frame[:3] + bytes([frame[3] ^ 0x10]) + frame[4:]
        stream += frame
    stream += doc.raw_frame(0x7E, 0, b"new") + b"\x01" * 80 + b"\x00"     # unknown type; overflow
    rx = doc.Receiver(LAYOUTS, {"command", "heartbeat"})
    rx.feed(stream)
    assert (rx.counts["sequence_gaps"], rx.counts["frames_lost"], rx.counts["crc_errors"]) == (3, 5, 1)
    assert (rx.counts["unknown_types"], rx.counts["overflows"]) == (1, 1)
    p = protocol.FrameParser(accept={protocol.TYPE_COMMAND, protocol.TYPE_HEARTBEAT})
    p.feed(stream)
    assert {k: v for k, v in p.counters().items()} == rx.counts


# ---------------------------------------------------------------- the bridge node over a pty
class DocDevice:
    """The device side on a pseudo-terminal, written with doc_protocol only."""

    def __init__(self, link: str):
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        os.symlink(os.ttyname(self.slave), link)
        self.rx = doc.Receiver(LAYOUTS, {"command", "heartbeat"})
        self.tx = doc.Sender(LAYOUTS)
        self.got: list = []          # (name, seq, values) from the bridge
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        import select
        while not self._stop.is_set():
            if select.select([self.master], [], [], 0.05)[0]:
                try:
                    self.got += self.rx.feed(os.read(self.master, 4096))
                except OSError:
                    return

    def write(self, data: bytes):
        os.write(self.master, data)

    def close(self):
        self._stop.set()
        self._reader.join(2.0)
        os.close(self.master)
        os.close(self.slave)


def values_of(diag: list, suffix: str) -> dict:
    for d in reversed(diag):
        for s in d.status:
            if s.name.endswith(suffix):
                return {kv.key: kv.value for kv in s.values}
    return {}


SENSOR_VALUES = {"device_time": 0, "boom_angle": -0.1234, "bucket_angle": 0.5678, "boom_rate": -0.191,
                 "bucket_rate": 0.2, "wheel_fl": 1.234, "wheel_fr": -2.345, "wheel_rear": 2.5,
                 "current_fl": 4.321, "current_fr": 5.5, "current_rear": 12.345, "valve_boom": 1,
                 "valve_bucket": 0, "flags": 1}


def test_bridge_and_doc_implementation_interoperate_over_a_pty(ros, tmp_path):
    link = str(tmp_path / "due")
    dev = DocDevice(link)
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": link}, tmp_path / "bridge.log")
    node = rclpy.create_node("doc_interop_test")
    js, diag, hw = [], [], []
    node.create_subscription(JointState, "/lhd/joint_states", js.append, 50)
    node.create_subscription(DiagnosticArray, "/diagnostics", diag.append, 10)
    node.create_subscription(DiagnosticStatus, "/lhd/hw/status", hw.append, 10)
    masses = []
    node.create_subscription(Float64, "/lhd/load_cell/mass", lambda m: masses.append(m.data), 50)
    pub = node.create_publisher(Float64MultiArray, "/lhd/cmd", 1)
    plan = {"i": 0}

    def send_sensor_frames(n, skip=(), corrupt=(), extra=None):
        """n sensor frames numbered by the document's rule; `skip`: numbered but not sent (lost);
        `corrupt`: one bit flipped (dropped for its CRC); `extra`: bytes sent after each frame."""
        for _ in range(n):
            i = plan["i"]
            plan["i"] += 1
            frame = dev.tx.frame("sensor", dict(SENSOR_VALUES, device_time=i * 10000))
            if i in corrupt:
                frame = frame[:5] + bytes([frame[5] ^ 0x04]) + frame[6:]
            if i not in skip:
                dev.write(frame)
            if extra:
                dev.write(extra)
            spin_until(node, lambda: False, timeout=0.01)

    try:
        assert spin_until(node, lambda: any(m[0] == "heartbeat" for m in dev.got), timeout=20.0), bridge.log()
        t_end = time.monotonic() + 20.0                   # until this subscriber is matched too
        while len(js) < 20 and time.monotonic() < t_end:
            send_sensor_frames(10)
        assert len(js) >= 20, bridge.log()
        # device -> host: the fields land where the document puts them, at its scales
        m = js[-1]
        assert list(m.position[:2]) == pytest.approx([-0.1234, 0.5678], abs=1e-9)
        assert list(m.velocity) == pytest.approx([-0.191, 0.2, 1.234, -2.345, 2.5, 2.5], abs=1e-9)
        assert spin_until(node, lambda: hw and dict((k.key, k.value) for k in hw[-1].values).get("current_rear_A")
                          == "12.345", timeout=5.0)
        kv = {k.key: k.value for k in hw[-1].values}
        assert (kv["current_fl_A"], kv["current_fr_A"], kv["valve_boom"], kv["valve_bucket"]) == \
            ("4.321", "5.5", "1", "0")
        # host -> device: commands decode, each type numbered from 0 without a gap (a zero first: the fresh
        # start the bridge waits for before it moves the machine)
        pub.publish(Float64MultiArray(data=[0.0, 0.0, 0.0]))
        send_sensor_frames(5)
        for _ in range(20):
            pub.publish(Float64MultiArray(data=[1.5, -0.191, 0.0]))
            send_sensor_frames(5)
        assert spin_until(node, lambda: sum(1 for g in dev.got if g[0] == "heartbeat") >= 2, timeout=5.0)
        cmds = [(s, v) for name, s, v in dev.got if name == "command"]
        beats = [s for name, s, _ in dev.got if name == "heartbeat"]
        assert [s for s, _ in cmds] == [i % 256 for i in range(len(cmds))]
        assert beats == list(range(len(beats)))
        assert cmds[0][1] == {"wheel_setpoint": 0.0, "valve_boom": 0, "valve_bucket": 0, "enable": 0}   # stop first
        assert {"wheel_setpoint": 1.5, "valve_boom": 1, "valve_bucket": 0, "enable": 1} in [v for _, v in cmds]
        assert dev.rx.counts == dict(dev.rx.counts, crc_errors=0, framing_errors=0, unknown_types=0, overflows=0,
                                     sequence_gaps=0, frames_lost=0)
        # drops, exactly as the document counts them: 1 lost, 3 lost in a row, 1 CRC-dropped
        # frame, frames of an unknown type and of the other direction in between, and the
        # counter wrapping from 255 to 0 (sensor frames so far: 120 or more; 310 more)
        base = plan["i"]
        other = doc.Sender(LAYOUTS)
        send_sensor_frames(50, skip={base + 5}, extra=doc.raw_frame(0x7E, 0, b"future"))
        send_sensor_frames(250, skip={base + 60, base + 61, base + 62}, corrupt={base + 120})
        for _ in range(4):
            dev.write(other.frame("command", {"wheel_setpoint": 0.0, "valve_boom": 0, "valve_bucket": 0,
                                              "enable": 0}))
        send_sensor_frames(10)
        want = {"crc_errors": "1", "framing_errors": "0", "overflows": "0", "unknown_types": "54",
                "sequence_gaps": "3", "frames_lost": "5", "frames": str(plan["i"] - 5)}
        ok = spin_until(node, lambda: {k: values_of(diag, "serial link").get(k) for k in want} == want,
                        timeout=5.0)
        assert ok, (values_of(diag, "serial link"), bridge.log())
        # load-cell frames written from the document: valid ones give their mass, one with the
        # saturated bit (2) or without the tared bit (1) gives nothing; their numbering is their own
        assert masses == []
        for k in range(20):
            flags = {5: 0x07, 6: 0x01}.get(k, 0x03)
            dev.write(dev.tx.frame("load_cell", {"device_time": k * 100000, "mass": 21.5 + k * 0.001,
                                                 "raw": 1_994_700 + k, "flags": flags}))
            send_sensor_frames(1)
        want_masses = [pytest.approx(21.5 + k * 0.001, abs=1e-9) for k in range(20) if k not in (5, 6)]
        assert spin_until(node, lambda: len(masses) >= 18, timeout=5.0), masses
        assert masses == want_masses
        assert spin_until(node, lambda: values_of(diag, "serial link").get("sequence_gaps") == "3", timeout=3.0)
    finally:
        node.destroy_node()
        assert bridge.stop() == 0, bridge.log()
        dev.close()


# ---------------------------------------------------------------- the firmware, compiled on this host
@pytest.fixture(scope="module")
def firmware(tmp_path_factory):
    if shutil.which("g++") is None:
        pytest.skip("no C++ compiler on this machine")
    out = tmp_path_factory.mktemp("fw") / "lhd_due"
    here = Path(__file__).parent / "firmware_host"
    subprocess.run(["g++", "-std=c++17", "-O1", "-Wall", "-Wextra", "-Werror", f"-I{here}", f"-I{FIRMWARE.parent}",
                    str(here / "main.cpp"), "-o", str(out)], check=True)
    return out


def test_firmware_speaks_the_document(firmware):
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    fw = subprocess.Popen([str(firmware)], stdin=slave, stdout=slave)
    rx = doc.Receiver(LAYOUTS, {"sensor"})
    tx = doc.Sender(LAYOUTS)
    got = []

    def read_for(seconds):
        import select
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            if select.select([master], [], [], 0.01)[0]:
                got.extend(rx.feed(os.read(master, 4096)))

    try:
        read_for(0.3)
        assert got and got[-1][2]["flags"] == 0x28                   # no command yet: held and reset since power-up
        cmd = {"wheel_setpoint": 9.0, "valve_boom": 1, "valve_bucket": -1, "enable": 1}
        os.write(master, doc.raw_frame(0x7E, 0, b"x") + b"\x05garbage\x00")   # ignored
        # the stop frame a host sends first on opening the port clears the hold
        os.write(master, tx.frame("command", {"wheel_setpoint": 0.0, "valve_boom": 0, "valve_bucket": 0, "enable": 0}))
        for _ in range(20):
            os.write(master, tx.frame("command", cmd))
            read_for(0.02)
        v = got[-1][2]
        assert v["flags"] & 0x01 and v["valve_boom"] == 1 and v["valve_bucket"] == 0   # forward tilt refused
        n = len(got)
        read_for(0.5)                                                  # commands stop: device watchdog
        after = [g[2] for g in got[n:]]
        assert after[-1]["flags"] == 0x02 and after[-1]["valve_boom"] == 0
        seqs = [s for _, s, _ in got]
        assert seqs == [i % 256 for i in range(len(seqs))]               # its one counter, from 0
        assert rx.counts == dict(rx.counts, crc_errors=0, framing_errors=0, sequence_gaps=0, frames_lost=0)
        # built without LHD_HAS_LOAD_CELL: no load-cell frame (it would count as a type not taken)
        assert rx.counts["unknown_types"] == 0
    finally:
        fw.kill()
        fw.wait()
        os.close(master)
        os.close(slave)
