"""What `lhd up real` prints for the operator: the preflight checklist (one line per problem, even
where a problem's sentence holds "; "; printed again only when the problems change, not their
figures) and the `m KG` key's refusals (a review, 2026-11-28: a typo was taken silently, a bad
mass vanished into the supervisor's log, the checklist split sentences and reprinted every second)."""
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from lhd_loading_ros.cli.up_real import (format_preflight, keep_earlier_logs, mass_refusal, preflight_key, preflight_problems,
                                         record_diag_line)

P1 = "joint states 0.90 s old (timeout 0.5 s; /lhd/joint_states, the bridge)"
P2 = "bucket tip already in the end zone (x 0.812, y 0.003, z 0.411 m): back the machine off to the attack pose"


def status(problems, with_values=True):
    st = DiagnosticStatus(name="/lhd_supervisor: preflight", message="not ready to arm: " + "; ".join(problems))
    if with_values:
        st.values = [KeyValue(key="problems", value=str(len(problems)))] + [
            KeyValue(key=f"problem_{k}", value=p) for k, p in enumerate(problems, 1)]
    return st


def test_each_problem_is_one_line_even_with_a_semicolon_inside():
    assert format_preflight(status([P1, P2])).splitlines() == [
        "preflight: not ready to arm", f"  [--] {P1}", f"  [--] {P2}"]
    # a supervisor without the values (an older one): the message split, as before
    assert preflight_problems(status(["no pile slope received", "no pile zones received"], False)) == [
        "no pile slope received", "no pile zones received"]
    assert format_preflight(DiagnosticStatus(message="ready to arm")) == "preflight: ready to arm"


def test_the_checklist_is_printed_again_when_its_problems_change_not_their_figures():
    older = P1.replace("0.90", "1.95")
    moved = P2.replace("0.812", "0.790").replace("0.003", "-0.010")
    assert preflight_key(status([P1, P2])) == preflight_key(status([older, moved]))
    assert preflight_key(status([P1, P2])) != preflight_key(status([P1]))
    assert preflight_key(status([P1])) != preflight_key(status([P1.replace("joint states", "odometry")]))
    assert preflight_key(DiagnosticStatus(message="ready to arm")) != preflight_key(status([P1]))


def test_record_errors_reach_the_console_once_per_change():
    """A review (2026-11-29): on a full disk the console printed "attempt 1 success" and the run exited 0
    while neither attempts.csv nor the bag was written; the errors were in the node logs only."""
    seen = {}
    sup, rec = "/lhd_supervisor: record", "/lhd_recorder: recording"
    assert record_diag_line(seen, sup, False, "record /r/attempts.csv") is None          # fine from the start
    assert record_diag_line(seen, sup, True, "cannot write /r/attempts.csv: [Errno 28] No space left on device") \
        == "record: ERROR cannot write /r/attempts.csv: [Errno 28] No space left on device"
    assert record_diag_line(seen, sup, True, "cannot write /r/attempts.csv: [Errno 28] No space left on device") is None
    assert record_diag_line(seen, rec, True, "idle; 1 bag(s) could not be opened or closed (see the log)") \
        == "recorder: ERROR idle; 1 bag(s) could not be opened or closed (see the log)"
    assert record_diag_line(seen, rec, True, "idle; 2 bag(s) could not be opened or closed (see the log)") is None
    assert record_diag_line(seen, sup, False, "record /r/attempts.csv") == "record: ok again: record /r/attempts.csv"
    assert record_diag_line(seen, sup, False, "record /r/attempts.csv") is None


def test_m_kg_refusals_name_what_is_wrong():
    ended = {"episode": "3", "state": "success", "ran": "true"}
    assert mass_refusal("23.4", ended) == ""
    for text, why in (("nan", "not a finite number"), ("-3", "negative"), ("500", "not a plausible bucket load"),
                      ("inf", "not a finite number"), ("1_0", "not a number"), ("23,4", "not a number")):
        msg = mass_refusal(text, ended)
        assert why in msg and "`m KG`, e.g. `m 23.4`" in msg, (text, msg)
    assert mass_refusal("23.4", {"episode": "0", "state": "idle"}) == (
        "no attempt has ended yet: weigh the bucket after the attempt ends")
    assert mass_refusal("23.4", {}) == "no attempt has ended yet: weigh the bucket after the attempt ends"
    assert mass_refusal("23.4", {"episode": "4", "state": "running"}) == (
        "attempt 4 is running: weigh the bucket after the attempt ends")
    assert mass_refusal("23.4", {"episode": "5", "state": "aborted", "ran": "false"}).startswith(
        "attempt 5 ended before it ran: nothing was loaded. To weigh an earlier attempt: "
        "`lhd attempt mass KG --attempt N`")


def test_output_cut_off_by_its_reader_ends_without_a_traceback(tmp_path):
    """`lhd attempts RUN | head`: the reader goes away before `lhd` writes (here: the pipe closed
    at once); a review saw a BrokenPipeError traceback. Status 1, nothing on stderr."""
    import subprocess
    import sys

    from lhd_loading_ros.task.attempt_record import AttemptRow, upsert_row

    for n in range(1, 4):
        upsert_row(tmp_path / "attempts.csv", AttemptRow(
            attempt=n, started_utc="2026-11-28T05:00:00Z", controller="rld", slope_deg=20.0, material="homogeneous",
            outcome="success", reason="end zone", mass_kg=25.0, elapsed_s=4.0, front_drift_pct=1.0,
            rear_drift_pct=2.0, phi_final_deg=45.0, success_level=5, success=True, bag=f"bags/attempt_{n:04d}"))
    p = subprocess.Popen([sys.executable, "-m", "lhd_loading_ros.cli.main", "attempts", str(tmp_path)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    p.stdout.close()
    err = p.stderr.read()
    assert p.wait(60) == 1 and "Traceback" not in err and "BrokenPipe" not in err, err
    whole = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "attempts", str(tmp_path)],
                           capture_output=True, text=True, timeout=60)
    assert whole.returncode == 0 and "RLD" in whole.stdout, whole.stderr


def test_an_earlier_runs_logs_are_moved_aside_not_overwritten(tmp_path):
    """A review (2026-11-29): `lhd up real` on a reused run folder overwrote yesterday's node logs."""
    import os

    logs = tmp_path / "logs"
    logs.mkdir()
    assert keep_earlier_logs(logs) is None
    (logs / "bridge.log").write_text("yesterday")
    (logs / "supervisor.log").write_text("yesterday too")
    os.utime(logs / "bridge.log", (1_700_000_000, 1_700_000_000))          # 2023-11-14 22:13:20 UTC
    os.utime(logs / "supervisor.log", (1_700_000_060, 1_700_000_060))
    dest = keep_earlier_logs(logs)
    assert dest == logs / "earlier_20231114-221420"
    assert (dest / "bridge.log").read_text() == "yesterday" and not list(logs.glob("*.log"))
    (logs / "bridge.log").write_text("again")
    os.utime(logs / "bridge.log", (1_700_000_060, 1_700_000_060))
    assert keep_earlier_logs(logs) == logs / "earlier_20231114-221420_2"
