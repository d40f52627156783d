"""`note_crash`, which `lhd up real` and `lhd up twin` call when a node died: the interrupted
attempt's row names the node, whether the supervisor recorded the end ("supervisor stopped during
the attempt") or died itself (the row written at arming, INTERRUPTED_REASON); a row that ended
otherwise is left alone. Rows made by hand with the record's own writer. And the launcher's
parameters for a node given an empty string."""
import math

from lhd_loading_ros.cli.up_real import note_crash
from lhd_loading_ros.task.attempt import INTERRUPTED_REASON
from lhd_loading_ros.task.attempt_record import AttemptRow, read_rows, upsert_row


def row(n, outcome, reason):
    return AttemptRow(attempt=n, started_utc="2026-11-28T05:00:00Z", controller="rld", slope_deg=20.0,
                      material="homogeneous", outcome=outcome, reason=reason, mass_kg=None, elapsed_s=0.0,
                      front_drift_pct=0.0, rear_drift_pct=0.0, phi_final_deg=math.nan, success_level=None,
                      success=False, bag=f"bags/attempt_{n:04d}")


def test_the_supervisors_own_death_is_named_in_the_row_it_wrote_at_arming(tmp_path, capsys):
    upsert_row(tmp_path / "attempts.csv", row(1, "failure", "bucket tip entered the restricted zone"))
    upsert_row(tmp_path / "attempts.csv", row(2, "aborted", INTERRUPTED_REASON))
    note_crash(tmp_path, "supervisor exited with status -9", "lhd up twin")
    rows = read_rows(tmp_path / "attempts.csv")
    assert [r.reason for r in rows] == ["bucket tip entered the restricted zone",
                                        "supervisor exited with status -9 during the attempt"]
    assert "lhd up twin: attempt 2 recorded as aborted" in capsys.readouterr().err


def test_another_nodes_death_and_a_row_that_ended_otherwise(tmp_path):
    upsert_row(tmp_path / "attempts.csv", row(1, "aborted", "supervisor stopped during the attempt"))
    note_crash(tmp_path, "controller exited with status -9")
    assert read_rows(tmp_path / "attempts.csv")[0].reason == (
        "controller exited with status -9 during the attempt: the launcher stopped the stack, the supervisor first")
    upsert_row(tmp_path / "attempts.csv", row(2, "aborted", "aborted by the operator"))
    note_crash(tmp_path, "mux exited with status 1")
    assert read_rows(tmp_path / "attempts.csv")[1].reason == "aborted by the operator"
    note_crash(tmp_path / "nowhere", "mux exited with status 1")        # no record: nothing to do, no error


def test_a_lost_input_end_just_before_the_death_was_found_names_the_node(tmp_path):
    """The supervisor saw the dead controller first, as commands that stopped, and recorded
    lost_input; the launcher found the dead process 0.4 s later: the row keeps its outcome and
    names the node. An end recorded 60 s before (another attempt's), or no time of finding, is left
    alone; so is a second note for the same node."""
    import os
    import time

    path = tmp_path / "attempts.csv"
    lost = "the controller's commands stopped: the command mux's auto source timed out"
    upsert_row(path, row(1, "lost_input", lost))
    written = path.stat().st_mtime
    note_crash(tmp_path, "controller exited with status -9")                       # no time: left alone
    assert read_rows(path)[0].reason == lost
    os.utime(path, (written - 60.0, written - 60.0))
    note_crash(tmp_path, "controller exited with status -9", found_at=written)     # 60 s after: left alone
    assert read_rows(path)[0].reason == lost
    os.utime(path, (written, written))
    note_crash(tmp_path, "controller exited with status -9", found_at=written + 0.4)
    r = read_rows(path)[0]
    assert (r.outcome, r.reason) == ("lost_input", f"{lost}; controller exited with status -9, found by the launcher "
                                                   "0.4 s after this end: the likely cause")
    note_crash(tmp_path, "controller exited with status -9", found_at=time.time())
    assert read_rows(path)[0].reason == r.reason                                    # once only


def test_the_launchers_parameters_start_a_node_with_an_empty_string(tmp_path):
    """`lhd up real --controller tampier` gives the supervisor policy_dir '' (no actor): the
    launcher's `-p` arguments must be parsed by ROS, and the node start with that value."""
    import os
    import subprocess
    import sys

    from lhd_loading_ros.cli.launcher import param_args
    from rosutil import unique_domain_id

    args = param_args({"run_dir": str(tmp_path), "policy_dir": "", "controller": "tampier"})
    assert args[2:4] == ["-p", "policy_dir:=''"], args
    env = dict(os.environ, ROS_DOMAIN_ID=str(unique_domain_id()))
    p = subprocess.Popen([sys.executable, "-m", "lhd_loading_ros.nodes.supervisor_node", "--ros-args", *args],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                         start_new_session=True)
    try:
        line = p.stdout.readline()
    finally:
        p.terminate()
        p.wait(30)
    assert "supervisor up" in line and "controller tampier" in line, line
