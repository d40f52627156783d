"""`lhd replay` on bags written here with rosbags' Writer (MCAP and sqlite3), messages built
and serialized (CDR) with rosbags' Jazzy typestore, at hand-chosen receive times: the
attempt window, elapsed time, drift % at the commands, final pitch, the tip's start from the
config's arm geometry, the stop delay, the mass from the run's attempts.csv, missing topics
said plainly, and exit 2 for what is not a bag. (The recorder's own bags: test/nodes/test_recorder.py.)"""
import json
import math
import re

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from lhd_loading_ros.cli import replay

TS = get_typestore(Stores.ROS2_JAZZY)
T = TS.types
S = 1_000_000_000
X0 = 0.1                    # base x in the pile frame at the first state (m)


def Float64(data):
    return T["std_msgs/msg/Float64"](data=float(data))


def Bool(data):
    return T["std_msgs/msg/Bool"](data=bool(data))


def Float64MultiArray(data):
    layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    return T["std_msgs/msg/Float64MultiArray"](layout=layout, data=np.array(data, dtype=np.float64))


def _header():
    return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="pile")


def JointState(name, position, velocity):
    return T["sensor_msgs/msg/JointState"](header=_header(), name=list(name), position=np.array(position, float),
                                           velocity=np.array(velocity, float), effort=np.array([], float))


def Odometry(x, z):
    v3 = T["geometry_msgs/msg/Vector3"]
    pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=0.0, z=z),
                                       orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    twist = T["geometry_msgs/msg/Twist"](linear=v3(x=0.2, y=0.0, z=0.0), angular=v3(x=0.0, y=0.0, z=0.0))
    return T["nav_msgs/msg/Odometry"](
        header=_header(), child_frame_id="base_link",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)))


def _status(state, attempt, stamp_ns, **extra):
    vals = {"state": state, "episode": str(attempt), "stamp_ns": str(stamp_ns), "controller": "teleop",
            "loaded_mass": "nan", "slope_deg": "20.000", "material": "homogeneous", **extra}
    kv = T["diagnostic_msgs/msg/KeyValue"]
    return T["diagnostic_msgs/msg/DiagnosticStatus"](level=0, name="lhd_supervisor/episode", message=state,
                                                     hardware_id="", values=[kv(key=k, value=v) for k, v in vals.items()])


def attempt_messages(cfg, with_odom=True):
    """(topic, t_ns, message) of attempt 4 (times in ns from 0): an old status of attempt 3,
    armed at 1 s, running at 2 s (stamp 2 s), ten commands at 2.05 + 0.1 k s, each 50 ms
    after its drift flags, the end (timeout) at 3 s (stamp 3.5 s: the supervisor's clock), a
    zero command 80 ms later, and the machine after the end (not the final pitch)."""
    r = cfg["machine"]["wheel_radius"]
    out = [("/lhd/pile/slope", 100, Float64(data=math.radians(20.0))),
           ("/lhd/pile/end_zone", 100, Float64MultiArray(data=[0.6, 1.0, 0.3])),
           ("/lhd/episode", int(0.5 * S), _status("success", 3, int(0.4 * S))),
           ("/lhd/episode", 1 * S, _status("armed", 4, 1 * S)),
           ("/lhd/episode", 2 * S, _status("running", 4, 2 * S))]
    for k in range(10):
        t = 2 * S + k * S // 10
        out.append(("/lhd/wheel_drift/front", t, Bool(data=k in (2, 3))))
        out.append(("/lhd/wheel_drift/rear", t, Bool(data=k <= 5)))
        boom, bucket = -0.1 * k / 9, 0.4 * k / 9
        out.append(("/lhd/joint_states", t + 10_000_000,
                    JointState(name=["boom", "bucket"], position=[boom, bucket], velocity=[0.0, 0.0])))
        if with_odom:
            out.append(("/lhd/odom", t + 20_000_000, Odometry(X0 + 0.01 * k, r)))
        out.append(("/lhd/cmd", t + 50_000_000, Float64MultiArray(data=[0.3 * k, -0.2 if k < 5 else 0.0, 0.1])))
    out.append(("/lhd/episode", 3 * S, _status("timeout", 4, int(3.5 * S), reason="10 s passed", elapsed_s="1.50",
                                               front_drift_pct="20.00", rear_drift_pct="60.00", phi_final_deg="28.65")))
    out.append(("/lhd/cmd", 3 * S + 80_000_000, Float64MultiArray(data=[0.0, 0.0, 0.0])))
    out.append(("/lhd/joint_states", 3 * S + 100_000_000,
                JointState(name=["boom", "bucket"], position=[-0.6, 1.4], velocity=[0.0, 0.0])))
    return out


def write_bag(path, messages, storage=StoragePlugin.MCAP, custom=None):
    conns = {}
    with Writer(path, version=9, storage_plugin=storage) as w:
        for k, v in (custom or {}).items():
            w.set_custom_data(k, v)
        for topic, t, msg in sorted(messages, key=lambda m: m[1]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msg.__msgtype__, typestore=TS)
            w.write(conns[topic], t, TS.serialize_cdr(msg, msg.__msgtype__))
    return path


def record_row(attempt, outcome, mass=None, elapsed=1.5, reason="r"):
    from lhd_loading_ros.task.attempt_record import AttemptRow, judge

    sl, ok = judge(outcome, mass, math.radians(45.0), math.radians(40.0))
    return AttemptRow(attempt=attempt, started_utc="2026-11-30T10:00:00Z", controller="teleop", slope_deg=20.0,
                      material="homogeneous", outcome=outcome, reason=reason, mass_kg=mass, elapsed_s=elapsed,
                      front_drift_pct=20.0, rear_drift_pct=60.0, phi_final_deg=45.0, success_level=sl, success=ok,
                      bag=f"bags/attempt_{attempt:04d}", phi_thresh_deg=40.0)


def write_record(run, rows):
    from lhd_loading_ros.task.attempt_record import write_rows

    write_rows(run / "attempts.csv", rows)


@pytest.mark.parametrize("storage", [StoragePlugin.MCAP, StoragePlugin.SQLITE3])
def test_the_metrics_of_an_attempt(cfg, tmp_path, capsys, storage):
    run = tmp_path / "run"
    bag = write_bag(run / "bags" / "attempt_0004", attempt_messages(cfg), storage, {"lhd.attempt": "4"})
    write_record(run, [record_row(3, "success", 21.0), record_row(4, "timeout", 23.4)])
    png = tmp_path / "out" / "a4.png"
    assert replay.main([str(bag), "--json", "--plot", str(png)]) == 0
    m = json.loads(capsys.readouterr().out)
    assert (m["attempt"], m["outcome"], m["reason"], m["controller"]) == (4, "timeout", "10 s passed", "teleop")
    assert m["elapsed_s"] == pytest.approx(1.5)          # the statuses' own stamps: 3.5 s - 2.0 s
    assert m["front_drift_pct"] == pytest.approx(20.0)   # flags set before commands 2 and 3 of 10
    assert m["rear_drift_pct"] == pytest.approx(60.0)    # commands 0..5 of 10
    assert m["drift_steps"] == 10
    # last joint state before the end: boom -0.1, bucket 0.4, base level: pitch = 0.4 + 0.1 rad
    assert m["final_pitch_deg"] == pytest.approx(math.degrees(0.5), abs=1e-9)
    c = m["commands"]
    assert c["count"] == 10 and c["rate_hz"] == pytest.approx(10.0)
    assert c["max_abs"] == pytest.approx([2.7, 0.2, 0.1])
    assert c["first_zero_after_end_ms"] == pytest.approx(80.0)
    # the first tip, joints at zero, base at (X0, 0, r), level: the attack pose of the config's
    # arm, i.e. x = wheelbase + pivot ahead of the front axle + boom reach + tip ahead of the
    # hinge, z = floor gap + plate (5 mm + 10 mm; offsets rounded to 10 um by the MJCF)
    mc = cfg["machine"]
    reach = math.sqrt(mc["boom_length"] ** 2 - (mc["boom_pivot_height"] - mc["bucket_hinge_height"]) ** 2)
    x_tip = X0 + mc["wheelbase"] + mc["boom_pivot_ahead_of_front_axle"] + reach + mc["bucket_tip_ahead_of_hinge"]
    assert m["tip"]["start_xz"] == pytest.approx([x_tip, 0.015], abs=1e-4)
    assert m["tip"]["samples_in_attempt"] == 10
    assert (m["loaded_mass_kg"], m["mass_source"]) == (23.4, "attempts.csv")
    assert m["pile"]["slope_deg"] == pytest.approx(20.0) and m["pile"]["end_zone"] == [0.6, 1.0, 0.3]
    assert m["missing"] == []
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert replay.main([str(bag)]) == 0
    text = capsys.readouterr().out
    assert "attempt 4: timeout (10 s passed)" in text
    assert re.search(r"elapsed \(s\) +1\.50 +1\.50\n", text) and re.search(r"final pitch \(deg\) +28\.65 +28\.65\n", text)
    assert "loaded mass: 23.40 kg (attempts.csv)" in text
    assert "stop: first zero command 80 ms after the end status" in text


def test_missing_topics_are_said_not_a_traceback(cfg, tmp_path, capsys):
    msgs = [m for m in attempt_messages(cfg, with_odom=False) if not m[0].startswith(("/lhd/wheel_drift/rear",
                                                                                      "/lhd/pile"))]
    bag = write_bag(tmp_path / "bag", msgs)
    assert replay.main([str(bag), "--plot", str(tmp_path / "p.png")]) == 0
    text = capsys.readouterr().out
    assert "missing: no /lhd/odom in the bag: no tip trajectory, no final pitch" in text
    assert "missing: no /lhd/wheel_drift/rear in the bag: no rear drift %" in text
    assert "missing: no /lhd/pile/slope in the bag: no pile face in the plot" in text
    assert "attempt 4: timeout" in text                # no custom data: the attempt of the running status
    assert (tmp_path / "p.png").stat().st_size > 0


def test_a_bag_without_an_attempt(cfg, tmp_path, capsys):
    bag = write_bag(tmp_path / "bag", [("/lhd/cmd", 5, Float64MultiArray(data=[1.0, 0.0, 0.0]))],
                    StoragePlugin.SQLITE3)
    assert replay.main([str(bag), "--json"]) == 0
    m = json.loads(capsys.readouterr().out)
    assert m["outcome"] is None and m["commands"]["count"] == 0
    assert any(line.startswith("no /lhd/episode in the bag") for line in m["missing"])


def test_what_is_not_a_bag_exits_2(tmp_path, capsys):
    assert replay.main([str(tmp_path / "nowhere")]) == 2
    assert "no such file or folder" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert replay.main([str(tmp_path / "empty")]) == 2
    assert "not a rosbag2 folder (no metadata.yaml)" in capsys.readouterr().err
    (tmp_path / "notes.txt").write_text("hello")
    assert replay.main([str(tmp_path / "notes.txt")]) == 2
    assert "not a rosbag2 folder" in capsys.readouterr().err
    # a recording that was never closed (recorder killed with SIGKILL): storage file, no metadata
    unclosed = tmp_path / "unclosed"
    unclosed.mkdir()
    (unclosed / "unclosed.mcap").write_bytes(b"\x89MCAP0\r\n")
    assert replay.main([str(unclosed / "unclosed.mcap")]) == 2
    assert "never closed" in capsys.readouterr().err
    bad = tmp_path / "badmeta"
    bad.mkdir()
    (bad / "metadata.yaml").write_text("rosbag2_bagfile_information: [")
    assert replay.main([str(bad)]) == 2
    assert "is not rosbag2 metadata" in capsys.readouterr().err


@pytest.mark.parametrize("edit, said", [
    # a spreadsheet's quoted decimal comma: lhd attempts refuses the file; replay said "not weighed yet"
    (lambda t: t.replace(",23.40,", ',"23,40",'), "mass_kg = '23,40' is not a number"),
    # a duplicated attempt: replay took the last row's mass
    (lambda t: t + t.splitlines()[2].replace(",23.40,", ",11.00,") + "\n", "attempt 4 on lines 3 and 4"),
])
def test_the_record_is_read_as_lhd_attempts_reads_it(cfg, tmp_path, capsys, edit, said):
    """A review (2026-11-30): replay parsed attempts.csv with its own code, quietly."""
    run = tmp_path / "run"
    bag = write_bag(run / "bags" / "attempt_0004", attempt_messages(cfg), custom={"lhd.attempt": "4"})
    write_record(run, [record_row(3, "success", 21.0), record_row(4, "timeout", 23.4)])
    csv = run / "attempts.csv"
    csv.write_text(edit(csv.read_text()))
    assert replay.main([str(bag)]) == 0
    text = capsys.readouterr().out
    assert "loaded mass: not weighed yet" in text and "11.00" not in text
    line = next(l for l in text.splitlines() if l.startswith("missing: the run's record cannot be read"))
    assert said in line, text


def test_a_bag_without_its_end_takes_the_outcome_from_the_record(cfg, tmp_path, capsys):
    """A review (2026-11-30): a recovered bag of an attempt the record calls aborted (its recorder died) was
    reported and titled 'attempt 4: running'."""
    run = tmp_path / "run"
    msgs = [m for m in attempt_messages(cfg) if m[1] < 3 * S]                 # cut before the end status
    bag = write_bag(run / "bags" / "attempt_0004_recovered", msgs)
    write_record(run, [record_row(4, "aborted", reason="aborted by the operator (/lhd/abort)")])
    assert replay.main([str(bag), "--json", "--plot", str(tmp_path / "p.png")]) == 0
    m = json.loads(capsys.readouterr().out)
    assert (m["attempt"], m["outcome"], m["end_in_bag"], m["outcome_source"]) == (4, "aborted", False, "attempts.csv")
    assert replay._title(m) == "attempt 4: aborted (attempts.csv; no end in the bag)"
    assert replay.main([str(bag)]) == 0
    text = capsys.readouterr().out
    assert ("attempt 4: aborted (aborted by the operator (/lhd/abort)) [from attempts.csv; no end in the bag]"
            in text), text
    (run / "attempts.csv").unlink()                                          # no record: said, not 'running' alone
    assert replay.main([str(bag), "--json"]) == 0
    m = json.loads(capsys.readouterr().out)
    assert m["outcome"] == "running" and replay._title(m) == "attempt 4: running (no end in the bag)"


def test_an_attempt_that_ended_while_armed_never_ran(cfg, tmp_path, capsys):
    """A review (2026-11-30): an attempt aborted while armed (ran=false) was 'not weighed yet ... lhd attempt
    mass KG' (which refuses it) with a final pitch from before arming."""
    run = tmp_path / "run"
    msgs = [m for m in attempt_messages(cfg) if m[0] != "/lhd/episode" or m[1] < 2 * S]
    msgs += [("/lhd/joint_states", int(1.2 * S), JointState(name=["boom", "bucket"], position=[-0.1, 0.4],
                                                               velocity=[0.0, 0.0])),
             ("/lhd/odom", int(1.2 * S), Odometry(X0, cfg["machine"]["wheel_radius"])),
             ("/lhd/episode", int(1.5 * S), _status("aborted", 4, int(1.5 * S), reason="aborted by the operator",
                                                    ran="false", elapsed_s="0.00"))]
    bag = write_bag(run / "bags" / "attempt_0004", [m for m in msgs if m[1] < int(1.6 * S)],
                    custom={"lhd.attempt": "4"})
    write_record(run, [record_row(4, "aborted", elapsed=0.0, reason="aborted by the operator")])
    assert replay.main([str(bag)]) == 0
    text = capsys.readouterr().out
    assert "attempt 4: aborted (aborted by the operator): it ended while armed and never ran" in text, text
    assert "not weighed yet" not in text and "lhd attempt mass" not in text
    assert "loaded mass: none, the attempt never ran" in text
    assert re.search(r"final pitch \(deg\) +- ", text), text
    assert replay.main([str(bag), "--json"]) == 0
    m = json.loads(capsys.readouterr().out)
    assert m["ran"] is False and m["final_pitch_deg"] is None and replay._title(m).endswith("(never ran)")


def test_a_cut_bag_with_its_metadata_points_to_bag_recover(cfg, tmp_path, capsys):
    """A review (2026-11-30): a bag whose copy was interrupted (metadata.yaml there, its .mcap cut) said only
    'File end magic is invalid'."""
    bag = write_bag(tmp_path / "bag", attempt_messages(cfg))
    f = next(bag.glob("*.mcap"))
    f.write_bytes(f.read_bytes()[:-200])
    assert replay.main([str(bag)]) == 2
    err = capsys.readouterr().err
    assert "cannot be read as a rosbag2" in err and f"`lhd bag recover {bag}`" in err, err


def test_a_number_used_twice_takes_nothing_from_the_other_attempts_row(cfg, tmp_path, capsys):
    """A review (2026-11-30): bags/attempt_0004_2 (a restarted supervisor reused number 4) took the outcome
    and the mass of the record's attempt 4, whose bag is bags/attempt_0004."""
    run = tmp_path / "run"
    bag = write_bag(run / "bags" / "attempt_0004_2", attempt_messages(cfg), custom={"lhd.attempt": "4"})
    write_record(run, [record_row(4, "timeout", 23.4)])
    assert replay.main([str(bag)]) == 0
    text = capsys.readouterr().out
    assert "23.40" not in text and "loaded mass: not weighed yet" in text, text
    assert "the record's attempt 4 names the bag bags/attempt_0004, not this one (attempt_0004_2" in text, text
