"""The supervisor node as a real process over DDS, fed by this test like the hardware stack
would feed it (joint states, odometry, drift flags, bridge status at 50 Hz; latched slope and
zones; the e-stop topic): arming refused with the reasons, arm -> running -> the tip moved
into the end zone -> success within 100 ms, the mass from `lhd attempt mass` into the row,
timeout after attempt_timeout, lost input, e-stop, abort, `lhd attempts` on the CSV the node
wrote, the load cell's mass, and an attempt cut short by stopping the node."""
import io
import math
import os
import signal
import subprocess
import sys
import time
from contextlib import redirect_stdout

import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import Bool, Float64, Float64MultiArray

from lhd_loading_ros.cli.attempts import main as attempts_main
from lhd_loading_ros.task.attempt_record import is_unended, read_rows

from fake_machine import FakeMachine, wait_for
from rosutil import RosProcess, init_ros, shutdown_ros

SUPERVISOR = "lhd_loading_ros.nodes.supervisor_node"
CLI = [sys.executable, "-m", "lhd_loading_ros.cli.attempts"]
TIMEOUT_S = 3.0          # attempt_timeout of this test's supervisor (room for a loaded machine)
ARM_DELAY = 0.3


def ended_row(rig, attempt):
    """The record's row of `attempt` once its end has replaced the row written at arming, else None."""
    rows = [r for r in read_rows(rig.run_dir / "attempts.csv") if r.attempt == attempt]
    return rows[0] if rows and not is_unended(rows[0]) else None


# Hand geometry (config/lhd_params.yaml, machine), as in test/task/test_attempt.py: in the
# attack pose the tip is 0.80 + 0.15 + sqrt(0.55^2 - 0.30^2) + 0.30 = 1.710977 m ahead of the
# rear axle, 0.015 m above the floor (axle at r = 0.137 m). Lifted (boom b, bucket k): about the
# boom pivot (0.95 m ahead, 0.42 m high), hinge offset (reach, -0.30) rotated by b, tip offset
# (0.30, -0.105) rotated by b - k; R_y: (x, z) -> (c x + s z, -s x + c z); pitch = k - b.
REACH = math.sqrt(0.55 ** 2 - 0.30 ** 2)


def rot(a, x, z):
    c, s = math.cos(a), math.sin(a)
    return c * x + s * z, -s * x + c * z


def tip_hand(base_x, boom, bucket):
    hx, hz = rot(boom, REACH, -0.30)
    tx, tz = rot(boom - bucket, 0.30, -0.105)
    return base_x + 0.95 + hx + tx, 0.42 + hz + tz


ZONES = [0.5, 1.0, 0.35, 1.5, -0.1, 1.1, 0.2, 0.4]    # x_min, x_max, z_min, x_cutoff, x_obs_start, x_obs_end, y_half, z_top
START = (-(0.80 + 0.15 + REACH + 0.30), 0.0, 0.0)     # base x, boom, bucket: tip at x = 0, on the floor
LIFT = (-0.5, 0.3)                                    # pitch 0.8 rad = 45.84 deg
END = (0.7 - tip_hand(0.0, *LIFT)[0], *LIFT)          # tip at x = 0.7, z = 0.52: in the end zone


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    init_ros()
    node = rclpy.create_node("test_supervisor")
    r = FakeMachine(node, START, front=True)
    r.feed = dict.fromkeys(r.feed, False)         # nothing yet: the first test arms without inputs
    r.run_dir = tmp_path_factory.mktemp("run")
    r.proc = RosProcess(SUPERVISOR, {"run_dir": str(r.run_dir), "attempt_timeout": TIMEOUT_S,
                                     "arm_delay": ARM_DELAY, "controller": "rld", "material": "homogeneous"},
                        r.run_dir.parent / "supervisor.log")
    yield r
    r.proc.stop()
    r.close()
    node.destroy_node()
    shutdown_ros()


def cli(*args, timeout=60):
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout)


def test_arm_refused_with_every_missing_input(rig):
    _, kv = rig.wait_state("idle", 0, timeout=60)
    assert kv["reason"] == "no attempt yet: call /lhd/arm" and kv["controller"] == "rld", rig.proc.log()
    res = rig.call(rig.arm_client)
    assert not res.success
    for what in ("no joint states received", "no odometry v_x received", "no front drift flag received",
                 "no rear drift flag received", "no bridge status received", "no pile slope received",
                 "no pile zones received"):
        assert what in res.message, res.message
    assert rig.state()["state"] == "idle"


def test_arm_refused_for_bad_zones_and_a_slope_out_of_range(rig):
    rig.feed = dict.fromkeys(rig.feed, True)
    rig.pub_slope.publish(Float64(data=math.radians(36.5)))
    rig.pub_zones.publish(Float64MultiArray(data=[1.0, 0.5] + ZONES[2:]))        # x_min > x_max
    time.sleep(0.5)
    res = rig.call(rig.arm_client)
    assert not res.success
    assert "pile zones invalid (/lhd/pile/zones): zones: x_min 1 must be below x_max 0.5" in res.message, res.message
    # no policy_dir: the config's alpha_min_deg up to the gravel's angle of repose, task.bucket_repose_deg,
    # each widened by 1 deg for the estimate's error
    assert "pile slope 36.5 deg is outside the controller's range [14, 36] deg" in res.message, res.message
    assert res.message.count(";") == 1, res.message          # those two problems only: every input is alive
    rig.pub_zones.publish(Float64MultiArray(data=ZONES))
    rig.pub_slope.publish(Float64(data=math.radians(20.0)))
    time.sleep(0.3)


def test_arm_refused_while_the_end_zone_node_refuses_the_pile_estimate(rig):
    """A field review (2026-11-29): when the end-zone node refuses a new LiDAR estimate (a toe beyond its
    limits, a slope in another frame) the last good zones stay latched, and the supervisor armed on the new
    pile's fresh slope with an earlier pile's zones. The real end-zone node, fed a toe 7 m out: its ERROR
    status on /diagnostics is a preflight item, kept after the node has gone (fail closed), until the node
    reports OK again on a good estimate."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import Vector3Stamped

    item = "the end-zone node refuses the latest pile estimate (/lhd/pile/slope_stamped: toe x 7.000 m: expected " \
           "|toe x| <= 5 m"
    preflight = []
    sub = rig.node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: preflight.extend(
        s.message for s in m.status if s.name == "/lhd_supervisor: preflight"), 50)
    pub = rig.node.create_publisher(Vector3Stamped, "/lhd/pile/slope_stamped", 10)

    def estimate(toe_x):
        m = Vector3Stamped()
        m.header.frame_id = "pile"
        m.vector.x, m.vector.y, m.vector.z = math.radians(20.0), toe_x, 0.01
        pub.publish(m)

    def listed():          # the supervisor's own checklist names it (no arming until then: it would arm)
        estimate(7.0)
        return any(item in s for s in preflight[-3:])

    ez = RosProcess("lhd_loading_ros.nodes.end_zone_node", {}, rig.run_dir.parent / "end_zone.log")
    try:
        assert wait_for(listed, 60.0), (preflight[-2:], ez.log())
        res = rig.call(rig.arm_client)
        assert not res.success and item in res.message, res.message
    finally:
        ez.stop()
    n = len(preflight)
    assert wait_for(lambda: len(preflight) > n + 8, 10.0)               # 2 s of checklists with the node gone
    assert all(item in s for s in preflight[-4:]), preflight[-1]         # still refused: fail closed
    ez = RosProcess("lhd_loading_ros.nodes.end_zone_node", {}, rig.run_dir.parent / "end_zone_2.log")
    try:
        def cleared():
            estimate(0.0)                                                # a good estimate: the node reports OK
            return preflight and not any(item in s for s in preflight[-2:])
        assert wait_for(cleared, 60.0), (preflight[-1:], ez.log())
    finally:
        ez.stop()
        rig.node.destroy_subscription(sub)
        rig.node.destroy_publisher(pub)
        rig.pub_zones.publish(Float64MultiArray(data=ZONES))            # the rig's own zones again
        time.sleep(0.3)


def test_arm_running_success_at_the_end_of_the_control_period(rig):
    n0 = len(rig.statuses)
    p = cli("arm")
    assert p.returncode == 0, p.stdout + p.stderr
    assert p.stdout.startswith(f"attempt 1 armed, running in {ARM_DELAY:g} s: controller rld, slope 20.0 deg"), p.stdout
    t_armed, _ = rig.wait_state("armed", 1, since=n0)
    t_run, kv = rig.wait_state("running", 1, since=n0)
    assert ARM_DELAY - 0.05 <= t_run - t_armed <= ARM_DELAY + 0.7, t_run - t_armed     # arm_delay, seen at 50 Hz
    assert float(kv["x_shovel"]) == pytest.approx(0.0, abs=1e-3) and float(kv["z_shovel"]) == pytest.approx(0.015,
                                                                                                           abs=1e-3)
    time.sleep(0.5)
    rig.set_pose(END)
    t_end, kv = rig.wait_state("success", 1, since=n0)
    latency = t_end - rig.pose_published_at[END]
    rig.set_pose(START)          # back to the start pose for the next tests, whatever is asserted below
    print(f"end-zone latency (joints published -> success status received): {latency * 1000:.1f} ms")
    # the end zone is judged at the end of each 0.1 s control period since running (as the task
    # judges it): at most a period, plus the 50 Hz check and the DDS hops
    assert latency < 0.1 + 0.1
    elapsed = float(kv["elapsed_s"])
    # on the period grid: the first check after a period's end (50 Hz timer, inputs at 50 Hz)
    assert abs(elapsed - round(elapsed / 0.1) * 0.1) < 0.05, elapsed
    x, z = tip_hand(END[0], *LIFT)
    assert float(kv["x_shovel"]) == pytest.approx(x, abs=1e-3) and float(kv["z_shovel"]) == pytest.approx(z, abs=1e-3)
    assert kv["phi_final_deg"] == "45.84" and kv["reason"] == "bucket tip reached the end zone"
    assert kv["front_drift_pct"] == "100.00" and kv["rear_drift_pct"] == "0.00"
    # running to the end, as this test saw the two statuses arrive
    assert float(kv["elapsed_s"]) == pytest.approx(t_end - t_run, abs=0.1) and float(kv["elapsed_s"]) >= 0.5
    assert kv["loaded_mass"] == "nan" and "success" not in kv
    # written right after the end status (status first: controllers stop on it), before any mass
    # (the row written at arming is there all along: wait for the end to replace it)
    assert wait_for(lambda: ended_row(rig, 1), 2.0)
    rows = read_rows(rig.run_dir / "attempts.csv")
    assert [(r.attempt, r.outcome, r.mass_kg, r.success) for r in rows] == [(1, "success", None, None)]
    assert rows[0].bag == "bags/attempt_0001" and rows[0].slope_deg == pytest.approx(20.0)
    from lhd_loading_ros.task.config import config_hash, load_config
    assert rows[0].config_hash == config_hash(load_config(None))       # the file the attempt was judged with
    # and its pitch threshold, which offline weighing judges the row on (the default file: 40 deg)
    assert rows[0].phi_thresh_deg == load_config(None)["paper"]["reward"]["phi_thresh_pitch_deg"] == 40.0


def test_mass_from_the_cli_updates_the_row(rig):
    p = cli("mass", "23.4")
    assert p.returncode == 0, p.stdout + p.stderr
    assert "attempt=1" in p.stdout and "mass_kg=23.40" in p.stdout and "success_level=2" in p.stdout \
        and "success=true" in p.stdout, p.stdout
    kv = rig.state()
    assert kv["loaded_mass"] == "23.40" and kv["success_level"] == "2" and kv["success"] == "True"
    row = read_rows(rig.run_dir / "attempts.csv")[0]
    assert (row.mass_kg, row.success_level, row.success) == (23.4, 2, True)


def test_timeout_after_attempt_timeout(rig):
    n0 = len(rig.statuses)
    assert rig.call(rig.arm_client).success
    t_run, _ = rig.wait_state("running", 2, since=n0)
    t_end, kv = rig.wait_state("timeout", 2, since=n0, timeout=TIMEOUT_S + 5)
    assert TIMEOUT_S - 0.1 <= t_end - t_run <= TIMEOUT_S + 0.4, t_end - t_run
    assert TIMEOUT_S <= float(kv["elapsed_s"]) <= TIMEOUT_S + 0.1      # seen by the 50 Hz check
    assert kv["reason"] == f"attempt_timeout {TIMEOUT_S:g} s passed"
    # mass refused while the next attempt is not ended is the CLI's check; here: nothing weighed yet
    assert "success" not in kv


def test_lost_input_when_the_joint_states_stop(rig):
    n0 = len(rig.statuses)
    assert rig.call(rig.arm_client).success
    rig.wait_state("running", 3, since=n0)
    rig.feed["joints"] = False
    time.sleep(0.05)
    t_last = rig.last_joints_at
    t_end, kv = rig.wait_state("lost_input", 3, since=n0)
    assert 0.5 <= t_end - t_last <= 0.5 + 0.3, t_end - t_last         # input_timeout, seen at 50 Hz
    assert "joint states" in kv["reason"] and "(timeout 0.5 s; /lhd/joint_states" in kv["reason"]
    rig.feed["joints"] = True
    time.sleep(0.1)


def test_estop_ends_the_attempt_and_blocks_arming(rig):
    n0 = len(rig.statuses)
    assert rig.call(rig.arm_client).success
    rig.wait_state("running", 4, since=n0)
    t0 = time.monotonic()
    rig.pub_estop.publish(Bool(data=True))
    t_end, kv = rig.wait_state("estop", 4, since=n0)
    assert t_end - t0 < 0.2          # the issue: e-stop to stopped within 300 ms, the mux and bridge included
    assert kv["reason"] == "emergency stop engaged (/lhd/estop is true)"
    res = rig.call(rig.arm_client)
    assert not res.success and "emergency stop engaged (/lhd/estop is true): release it first" in res.message
    rig.pub_estop.publish(Bool(data=False))
    # a load cell: once the machine stands still (joint velocities 0) for mass_settle_s (1 s),
    # the median of its readings is the attempt's mass. 22.004 kg: a row of 22.00 (the record's 10 g)
    rig.load_cell = 22.004
    _, kv = rig.wait_state("estop", 4, since=n0, timeout=1.0)
    assert wait_for(lambda: rig.state().get("mass_source") == "load_cell", 5.0), rig.state()
    time.sleep(1.0)
    rig.load_cell = None
    # weighed once: one line, one write (a row compared with the unrounded mass was rewritten and
    # logged at 50 Hz until the next arming: 2026-11-29)
    log = (rig.run_dir.parent / "supervisor.log").read_text()
    assert log.count("attempt 4: load cell 22.00 kg") == 1, log[-2000:]
    kv = rig.state()
    assert kv["loaded_mass"] == "22.00" and kv["success"] == "False" and kv["success_level"] == "0"   # pitch 0
    row = read_rows(rig.run_dir / "attempts.csv")[3]
    assert (row.attempt, row.mass_kg, row.success) == (4, 22.0, False)


def test_abort_from_the_cli(rig):
    # the CLI takes seconds to start on a loaded machine: a longer timeout for this attempt,
    # set at run time (it applies from the next arming)
    client = AsyncParameterClient(rig.node, "/lhd_supervisor")
    assert client.wait_for_services(20.0)
    fut = client.set_parameters([Parameter("attempt_timeout", Parameter.Type.DOUBLE, 60.0)])
    assert wait_for(fut.done, 20.0) and fut.result().results[0].successful
    assert wait_for(lambda: "parameter 'attempt_timeout' set to 60.0 at run time: the paper's 10 s" in rig.proc.log(),
                    5.0), rig.proc.log()[-1500:]           # a safety setting: said as a warning
    fut = client.set_parameters([Parameter("status_timeout", Parameter.Type.DOUBLE, 0.0)])
    assert wait_for(fut.done, 20.0) and not fut.result().results[0].successful      # fixed at start
    assert "read-only" in fut.result().results[0].reason, fut.result().results[0].reason
    n0 = len(rig.statuses)
    p = cli("arm")
    assert p.returncode == 0, p.stderr
    rig.wait_state("running", 5, since=n0)
    p = cli("abort")
    assert (p.returncode, p.stdout.strip()) == (0, "attempt 5 aborted"), p.stderr
    _, kv = rig.wait_state("aborted", 5, since=n0)
    assert kv["reason"] == "aborted by the operator (/lhd/abort)"
    p = cli("abort")
    assert (p.returncode, p.stdout.strip()) == (1, "nothing to abort: attempt 5 already ended (aborted)")
    p = cli("mass", "250")
    assert p.returncode == 2 and "not a plausible bucket load" in p.stderr


def test_lhd_attempts_on_the_record_the_node_wrote(rig):
    rows = read_rows(rig.run_dir / "attempts.csv")
    assert [(r.attempt, r.outcome) for r in rows] == [(1, "success"), (2, "timeout"), (3, "lost_input"),
                                                      (4, "estop"), (5, "aborted")]
    buf = io.StringIO()
    with redirect_stdout(buf):
        assert attempts_main([str(rig.run_dir)]) == 0
    out = buf.getvalue()
    print(out)
    # counted: 1 (success, 23.4 kg), 3 (lost input), 4 (e-stop); 2 waits for its mass; 5 aborted
    assert "5 attempt(s) recorded, 3 counted" in out
    assert "not yet weighed, not counted (lhd attempt mass KG --attempt N): attempt(s) 2" in out
    assert "aborted (by the operator, or not started by the supervisor) or ended before they ran, not counted: attempt(s) 5" in out
    lines = out.splitlines()
    assert lines[0] == f"Attempts in {rig.run_dir / 'attempts.csv'}"
    assert next(l for l in lines[1:] if l.startswith("Attempts")).split() == ["Attempts", "20", "3"]
    assert next(l for l in lines if l.startswith("Success rate")).split() == ["Success", "rate", "20", "0.33"]
    assert next(l for l in lines if l.startswith("Material loaded")).split()[3:] == ["20", "23.40±0.00"]
    # the earlier attempt 2 weighed through the CLI: the record is edited, attempt 2 counted
    p = cli("mass", "24.5", "--attempt", "2")
    assert p.returncode == 0 and "attempt=2" in p.stdout and "success=false" in p.stdout, p.stdout + p.stderr
    assert read_rows(rig.run_dir / "attempts.csv")[1].mass_kg == 24.5     # pitch 0 at the timeout: SL 0


def pause(proc, seconds):
    """Stop the node's process (SIGSTOP: what CPU starvation or a swap pause does) for `seconds`."""
    os.kill(proc.proc.pid, signal.SIGSTOP)
    try:
        time.sleep(seconds)
    finally:
        os.kill(proc.proc.pid, signal.SIGCONT)


def test_a_paused_supervisor_does_not_take_queued_inputs_for_lost_ones(rig):
    """The supervisor's process is paused for 1 s (SIGSTOP: what CPU starvation or a swap pause
    does to it) while the machine keeps publishing at 50 Hz. On waking, its executor runs the
    50 Hz check before it takes the queued messages; the inputs' ages then discount the pause
    (task.attempt.STALL_S), so the attempt keeps running. Then the inputs really stop: lost
    input, as before."""
    n0 = len(rig.statuses)
    assert rig.call(rig.arm_client).success          # attempt_timeout is 60 s since the CLI test
    rig.wait_state("running", 6, since=n0)
    pause(rig.proc, 1.0)
    n1 = len(rig.statuses)
    time.sleep(1.5)
    states = [(kv.get("state"), kv.get("episode")) for _, kv in rig.statuses[n1:]]
    assert states and all(st == ("running", "6") for st in states), states
    rig.feed["joints"] = False
    _, kv = rig.wait_state("lost_input", 6, since=n1)
    assert "joint states" in kv["reason"]
    rig.feed["joints"] = True
    time.sleep(0.1)


def test_a_supervisor_stalled_past_the_controllers_status_timeout_aborts_the_attempt(rig):
    """Paused for 2.5 s mid-attempt, the supervisor sent no status for longer than the controllers
    wait for one (status_timeout 1.5 s): the policy node and the mux have stopped the machine. On
    waking it must not run the attempt on to its timeout with nobody commanding (recorded as a plain
    timeout, or a success by the timeout rule): the attempt is aborted, saying why. Found by a
    reviewer helper on the twin (2026-11-28); the 1 s pause above still runs on."""
    n0 = len(rig.statuses)
    assert rig.call(rig.arm_client).success
    rig.wait_state("running", 7, since=n0)
    pause(rig.proc, 2.5)
    _, kv = rig.wait_state("aborted", 7, since=n0)
    assert kv["reason"].startswith("the supervisor did not run for 2.") and "status_timeout (1.5 s)" in kv["reason"]
    # the status goes out first, then the record (the controllers stop on the status)
    assert wait_for(lambda: ended_row(rig, 7), 10.0)
    row = read_rows(rig.run_dir / "attempts.csv")[-1]
    assert row.outcome == "aborted" and "did not run for" in row.reason


def arm_when_ready(rig, timeout=15.0):
    """Arm, retrying while the preflight refuses: after a stall of the supervisor the reliable
    latched slope can lag by up to a heartbeat of its writer (seen in CI: "pile slope 2.6 s old")."""
    t_end = time.monotonic() + timeout
    while True:
        res = rig.call(rig.arm_client)
        if res.success or time.monotonic() > t_end:
            return res
        time.sleep(0.5)


def test_stopping_the_node_mid_attempt_records_it_aborted(rig):
    n0 = len(rig.statuses)
    res = arm_when_ready(rig)
    assert res.success, res.message
    rig.wait_state("running", 8, since=n0)
    assert rig.proc.stop() == 0, rig.proc.log()
    _, kv = rig.wait_state("aborted", 8, since=n0)
    assert kv["reason"] == "supervisor stopped during the attempt"
    row = read_rows(rig.run_dir / "attempts.csv")[-1]
    assert (row.attempt, row.outcome, row.reason) == (8, "aborted", "supervisor stopped during the attempt")


def test_a_supervisor_killed_mid_attempt_leaves_the_attempt_in_the_record(rig):
    """SIGKILL (or a power cut) gives the node no chance to record the end. The row it wrote at
    arming stays: the attempt as aborted, why, and its bag; a supervisor started again on the same
    run folder goes on at the next number. Before 2026-11-28 the row was written only at the end
    and such an attempt vanished from attempts.csv (a review's fault injection)."""
    import signal

    from lhd_loading_ros.task.attempt import INTERRUPTED_REASON

    params = {"run_dir": str(rig.run_dir), "attempt_timeout": TIMEOUT_S, "arm_delay": ARM_DELAY,
              "controller": "rld", "material": "homogeneous"}
    rig.proc.stop()          # the module's supervisor, if a test before failed ahead of its stop
    rig.proc = RosProcess(SUPERVISOR, params, rig.run_dir.parent / "supervisor_2.log")
    n0 = len(rig.statuses)
    res = arm_when_ready(rig)
    assert res.success and res.message.startswith("attempt 9 armed"), res.message
    rig.wait_state("running", 9, since=n0)
    os.killpg(rig.proc.proc.pid, signal.SIGKILL)
    assert rig.proc.proc.wait(10) == -signal.SIGKILL
    row = read_rows(rig.run_dir / "attempts.csv")[-1]
    assert (row.attempt, row.outcome, row.reason, row.bag, row.success) == (
        9, "aborted", INTERRUPTED_REASON, "bags/attempt_0009", False), row
    rig.proc.stop()
    rig.proc = RosProcess(SUPERVISOR, params, rig.run_dir.parent / "supervisor_3.log")
    assert wait_for(lambda: "(next attempt 10)" in rig.proc.log(), 60.0), rig.proc.log()


def test_numbering_goes_on_from_the_bags_when_the_record_was_moved_away(tmp_path):
    """A review (2026-11-29): with attempts.csv moved aside (as the unreadable-record message asks), the
    numbering restarted at 1 beside yesterday's bags/attempt_0001..7, so today's attempt 1 was filed as
    attempt_0001_2 while its row named yesterday's bag. It goes on from the highest of both."""
    (tmp_path / "bags" / "attempt_0007").mkdir(parents=True)
    (tmp_path / "bags" / "attempt_0003_2").mkdir()
    p = RosProcess(SUPERVISOR, {"run_dir": str(tmp_path)}, tmp_path / "sv.log")
    try:
        assert wait_for(lambda: "(next attempt 8)" in p.log(), 60.0), p.log()
    finally:
        p.stop()


def test_an_unreadable_record_stops_the_node_with_one_line(tmp_path):
    (tmp_path / "attempts.csv").write_text("not,a,record\n1,2,3\n")
    p = RosProcess(SUPERVISOR, {"run_dir": str(tmp_path)}, tmp_path / "sv.log")
    assert p.proc.wait(60) == 2, p.log()
    p.stop()
    log = p.log().strip()
    assert "parameter 'run_dir'" in log and "not an attempts record" in log and "Traceback" not in log
    assert len(log.splitlines()) == 1, log


def test_slope_limits_narrow_the_controllers_range_and_never_widen_it(tmp_path):
    """`slope_limits_deg` (the real stack sets the machine actor's validated slopes): the range the
    supervisor arms on is the controller's within the limits; limits wider than it change nothing; limits
    that leave no slope stop the node at start with one line (exit 2), over a real process."""
    from lhd_loading_ros.nodes.supervisor_node import limited_slope_range_deg

    assert limited_slope_range_deg(10.0, 35.0, "card", [14.0, 35.0]) == (14.0, 35.0, "card, within slope_limits_deg [14, 35]")
    assert limited_slope_range_deg(15.0, 30.0, "card", [0.0, 90.0]) == (15.0, 30.0, "card")
    assert limited_slope_range_deg(15.0, 30.0, "card", [10.0, 35.0]) == (15.0, 30.0, "card")     # never widened
    p = RosProcess(SUPERVISOR, {"run_dir": str(tmp_path), "slope_limits_deg": [40.0, 50.0]}, tmp_path / "sv.log")
    assert p.proc.wait(60) == 2, p.log()
    p.stop()
    log = p.log().strip()
    assert "parameter 'slope_limits_deg' = [40, 50] leaves no slope of the controller's range [14, 36] deg" in log, log
    assert "Traceback" not in log and len(log.splitlines()) == 1, log
