"""The supervisor's `required_listeners` as real processes over DDS: with the recorder named, an
attempt is refused while no `lhd_recorder` subscribes to /lhd/episode (the preflight names it, in
the arm answer and on /diagnostics), and once the real recorder node runs the attempt is armed and
recorded into a bag. Before this item an attempt armed within the recorder's first second of
discovery had no bag (CI, 2026-11-28). A malformed name is refused at start with the parameter's
name."""
import subprocess
import sys
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray

from fake_machine import SUPERVISOR, close_rig, supervisor_rig, wait_for
from rosutil import RosProcess
from test_supervisor_node import END, START, ZONES

RECORDER = "lhd_loading_ros.nodes.recorder_node"


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    r = supervisor_rig(tmp_path_factory, "test_supervisor_listeners", {
        "attempt_timeout": 5.0, "arm_delay": 0.2, "required_listeners": "['lhd_recorder']"}, START, zones=ZONES)
    r.diag = []
    r.node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: r.diag.extend(
        s for s in m.status if s.name.endswith("supervisor: preflight")), 10)
    r.recorder = None
    yield r
    if r.recorder is not None:
        r.recorder.stop()
    close_rig(r)


def test_no_attempt_without_the_recorder_then_one_with_its_bag(rig):
    rig.wait_state("idle", 0, timeout=60)
    time.sleep(0.5)                                   # every input alive
    res = rig.call(rig.arm_client)
    assert not res.success, res.message
    # the only problem left is the missing listener: every input is alive
    assert res.message == ("not armed: node lhd_recorder does not listen to /lhd/episode yet (required_listeners): "
                           "it would miss the attempt (is it running?)"), res.message
    assert wait_for(lambda: any("lhd_recorder does not listen" in s.message for s in rig.diag), 10.0), \
        [s.message for s in rig.diag[-3:]]

    rig.recorder = RosProcess(RECORDER, {"run_dir": str(rig.run_dir)}, rig.run_dir.parent / "recorder.log")
    deadline, res = time.monotonic() + 60.0, None
    while time.monotonic() < deadline:                 # the recorder starting and being discovered
        res = rig.call(rig.arm_client)
        if res.success:
            break
        assert "lhd_recorder does not listen" in res.message, res.message
        time.sleep(0.5)
    assert res is not None and res.success, f"{res and res.message}\n{rig.recorder.log()}"
    n0 = len(rig.statuses)
    rig.wait_state("running", 1, since=n0 - 5 if n0 >= 5 else 0)
    # the recorder starts the attempt's bag: a real attempt lasts seconds, this one ends at the next
    # pose, so wait for it (under load the recorder's data path to /lhd/episode matched after the
    # supervisor saw it in the graph, and an attempt ended at once was over before it heard it start)
    assert wait_for(lambda: any(f"attempt 1 {st}: recording into" in rig.recorder.log() for st in ("armed", "running")),
                    5.0), rig.recorder.log()
    rig.set_pose(END)
    rig.wait_state("success", 1)
    rig.set_pose(START)
    assert wait_for(lambda: any("ready to arm" == s.message for s in rig.diag[-4:]), 10.0), \
        [s.message for s in rig.diag[-3:]]
    # the recorder wrote the attempt's bag (closed after its post-roll)
    bag = rig.run_dir / "bags" / "attempt_0001"
    assert wait_for(lambda: bag.is_dir() and any(bag.glob("*.mcap")) and (bag / "metadata.yaml").exists(), 20.0), \
        (sorted(rig.run_dir.rglob("*")), rig.recorder.log())


def arm_when_ready(rig, timeout=60.0):
    deadline, res = time.monotonic() + timeout, None
    while time.monotonic() < deadline:
        res = rig.call(rig.arm_client)
        if res.success:
            return res
        time.sleep(0.5)
    raise AssertionError(f"{res and res.message}\n{rig.recorder.log() if rig.recorder else ''}")


def test_a_record_that_cannot_be_written_refuses_arming_and_loses_no_row(rig):
    """A review (2026-11-29): on a full disk the attempts ran, the console printed them, and neither
    attempts.csv nor the bags were written. The supervisor keeps a row whose write failed, refuses to arm
    while it is unwritten (naming it) or while the record is no writable file, and writes it once the
    record can be written again, before the next attempt's row."""
    from lhd_loading_ros.task.attempt_record import read_rows

    csv = rig.run_dir / "attempts.csv"
    assert csv.is_file()
    # the first test's recorder was stopped at its end (conftest: no process outlives its test): a new one
    rig.recorder = RosProcess(RECORDER, {"run_dir": str(rig.run_dir)}, rig.run_dir.parent / "recorder2.log")
    n0 = len(rig.statuses)
    arm_when_ready(rig)
    rig.wait_state("running", 2, since=n0)
    saved = csv.with_name("attempts.saved")
    csv.rename(saved)
    csv.mkdir()                                    # the record unwritable (as root, permissions would not do)
    rig.set_pose(END)
    rig.wait_state("success", 2)
    rig.set_pose(START)
    time.sleep(0.5)
    res = rig.call(rig.arm_client)
    assert not res.success, res.message
    assert "attempt(s) 2 not yet written to the record" in res.message, res.message
    assert "is not a writable file" in res.message, res.message
    csv.rmdir()
    saved.rename(csv)                              # repaired: the row of attempt 2 goes in first
    n1 = len(rig.statuses)
    arm_when_ready(rig)
    rig.wait_state("running", 3, since=n1)
    rows = {r.attempt: r for r in read_rows(csv)}
    assert sorted(rows) == [1, 2, 3], rows
    assert rows[2].outcome == "success", rows[2]
    rig.set_pose(END)
    rig.wait_state("success", 3)
    rig.set_pose(START)


def test_a_malformed_node_name_is_refused_with_the_parameter(tmp_path):
    p = subprocess.run([sys.executable, "-m", SUPERVISOR, "--ros-args", "-p", f"run_dir:={tmp_path}",
                        "-p", "required_listeners:=['lhd recorder']"], capture_output=True, text=True, timeout=60)
    assert p.returncode != 0
    err = p.stdout + p.stderr
    assert "required_listeners" in err and "'lhd recorder'" in err and "lhd_recorder" in err, err
    assert "Traceback" not in err, err


def test_the_listener_item_is_one_line_of_lhd_up_reals_checklist(rig):
    """`lhd up real` prints the preflight's problems one per line, split on '; ': the listener's
    sentence must not be split (taken from the node's own /diagnostics)."""
    from lhd_loading_ros.cli.up_real import format_preflight

    if rig.recorder is not None:
        rig.recorder.stop()                            # the recorder gone: the item comes back
    assert wait_for(lambda: any("lhd_recorder does not listen" in s.message for s in rig.diag[-4:]), 20.0), \
        [s.message for s in rig.diag[-3:]]
    st = next(s for s in reversed(rig.diag) if "lhd_recorder does not listen" in s.message)
    lines = format_preflight(st).splitlines()
    assert lines[0] == "preflight: not ready to arm", lines
    assert lines[1:] == ["  [--] node lhd_recorder does not listen to /lhd/episode yet (required_listeners): it would "
                         "miss the attempt (is it running?)"], lines
