"""`lhd attempts`, `lhd attempt mass`, `lhd arm` / `lhd abort` (cli/attempts.py) without a
supervisor: the table of a hand-written record (text and JSON, hand-computed figures), the
refusals with their messages and exit statuses, the offline weighing of a run folder, and the
answer when no supervisor is there. With a supervisor: test/nodes/test_supervisor_node.py."""
import io
import json
import os
import subprocess
import sys
from contextlib import redirect_stderr, redirect_stdout

import pytest

from lhd_loading_ros.cli.attempts import attempt_mass_main, main as attempts_main
from lhd_loading_ros.task.attempt_record import COLUMNS, read_rows

CLI = [sys.executable, "-m", "lhd_loading_ros.cli.attempts"]
HEAD = ",".join(COLUMNS)
# attempt, started_utc, controller, slope_deg, material, outcome, reason, mass_kg, elapsed_s, front, rear,
# phi_final_deg, success_level, success, bag
RECORD = "\n".join([
    HEAD,
    "1,2025-03-01T10:00:00Z,rld,15.3,homogeneous,success,end zone,23.0,4.0,20,50,45,2,true,bags/attempt_0001",
    "2,2025-03-01T10:01:00Z,rld,14.8,homogeneous,success,end zone,25.0,5.0,30,60,44,3,true,bags/attempt_0002",
    "3,2025-03-01T10:02:00Z,rld,15.0,homogeneous,failure,restricted,,1.0,0,0,10,,false,bags/attempt_0003",
    "4,2025-03-01T10:03:00Z,teleop,25.0,nonhomogeneous,timeout,timeout,21.0,10.0,10,70,50,1,true,bags/attempt_0004",
    "5,2025-03-01T10:04:00Z,teleop,25.0,nonhomogeneous,success,end zone,,8.0,10,70,50,,,bags/attempt_0005",
    "6,2025-03-01T10:05:00Z,rld,15.0,homogeneous,aborted,aborted by the operator,,0.5,0,0,0,,false,bags/attempt_0006",
]) + "\n"


def run(fn, argv):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        rc = fn(argv)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture
def run_dir(tmp_path):
    (tmp_path / "attempts.csv").write_text(RECORD)
    return tmp_path


def test_table_of_a_record(run_dir):
    rc, out, _ = run(attempts_main, [str(run_dir)])
    assert rc == 0
    lines = out.splitlines()
    assert "6 attempt(s) recorded, 4 counted" in out
    assert "aborted (by the operator, or not started by the supervisor) or ended before they ran, not counted: attempt(s) 6" in out
    assert "not yet weighed, not counted (lhd attempt mass KG --attempt N): attempt(s) 5" in out
    labels = next(l for l in lines if l.lstrip().startswith("slope"))
    assert labels.split() == ["slope", "RLD", "Teleop"]
    # rld at 15 deg: 3 counted, 2 successes: 0.67; mass (23 + 25) / 2 = 24 +- 1; time 4.5 +- 0.5
    rate = [l.split() for l in lines if l.startswith("Success rate") or (l.startswith(" ") and "0.67" in l)]
    assert ["Success", "rate", "15", "0.67"] in rate
    mass = [l.split() for l in lines if l.startswith("Material loaded")][0]
    assert mass == ["Material", "loaded", "[kg]", "15", "24.00±1.00"]
    elapsed = [l.split() for l in lines if l.startswith("Elapsed time")][0]
    assert elapsed == ["Elapsed", "time", "[s]", "15", "4.50±0.50"]
    assert any(l.split() == ["25", "21.00±0.00"] for l in lines)      # teleop, nonhomogeneous, 25 deg (a timeout)


def test_table_as_json_and_the_csv_path_itself(run_dir):
    rc, out, _ = run(attempts_main, [str(run_dir / "attempts.csv"), "--json"])
    assert rc == 0
    d = json.loads(out)
    assert d["rows"] == 6 and d["counted"] == 4 and d["aborted"] == [6] and d["not_weighed"] == [5]
    cell = next(c for c in d["cells"] if c["controller"] == "rld")
    assert (cell["slope_deg"], cell["attempts"], cell["successes"]) == (15.0, 3, 2)
    assert cell["front_drift_pct"] == {"mean": 25.0, "std": 5.0, "n": 2}
    assert cell["rear_drift_pct"] == {"mean": 55.0, "std": 5.0, "n": 2}


def test_missing_and_broken_records(tmp_path):
    rc, _, err = run(attempts_main, [str(tmp_path / "nope")])
    assert rc == 1 and "no attempts.csv at" in err and "supervisor's run_dir" in err
    (tmp_path / "attempts.csv").write_text(HEAD + "\n1,t,rld,20,homogeneous,success,r,,four,0,0,45,,,b\n")
    rc, _, err = run(attempts_main, [str(tmp_path)])
    assert rc == 1 and "line 2: elapsed_s = 'four' is not a number" in err


@pytest.mark.parametrize("kg, message", [("nan", "not a finite number"), ("-1", "negative"),
                                         ("250", "not a plausible bucket load"), ("heavy", "not a number")])
def test_mass_refusals_are_exit_2_with_the_reason(kg, message):
    rc, out, err = run(attempt_mass_main, ["--", kg] if kg.startswith("-") else [kg])
    assert rc == 2 and out == "" and err.startswith("lhd attempt mass: refused: ") and message in err


def test_mass_into_a_run_folder_without_a_supervisor(run_dir):
    before = read_rows(run_dir / "attempts.csv")
    rc, out, err = run(attempt_mass_main, ["26.5", "--run-dir", str(run_dir), "--attempt", "5"])
    assert rc == 0, err
    assert "attempt=5" in out and "mass_kg=26.50" in out and "success_level=4" in out and "success=true" in out
    rows = read_rows(run_dir / "attempts.csv")
    assert (rows[4].mass_kg, rows[4].success_level, rows[4].success) == (26.5, 4, True)
    assert rows[:4] + rows[5:] == before[:4] + before[5:]           # the other rows untouched
    rc, _, err = run(attempt_mass_main, ["20", "--run-dir", str(run_dir), "--attempt", "9"])
    assert rc == 1 and "no attempt 9" in err


def test_offline_weighing_says_what_it_replaced_and_what_still_waits(run_dir):
    """A review (2026-11-29): `lhd attempt mass` replaced an earlier mass without a word, and said nothing of
    an attempt still waiting for its mass."""
    rc, out, err = run(attempt_mass_main, ["22", "--run-dir", str(run_dir), "--attempt", "4"])
    assert rc == 0, err
    assert "attempt 4: 21.00 kg replaced by 22.00 kg" in out, out
    assert "still unweighed: attempt(s) 5 (`lhd attempt mass KG --attempt N`)" in out, out
    rc, out, err = run(attempt_mass_main, ["26.5", "--run-dir", str(run_dir), "--attempt", "5"])
    assert rc == 0 and "replaced" not in out and "still unweighed" not in out, out


def test_offline_weighing_judges_on_the_rows_own_pitch_threshold(tmp_path):
    """A review (2026-11-29): offline weighing judged every row on the default file's pitch threshold
    (40 deg), whatever file the supervisor ran. A row now carries its supervisor's threshold: attempt 5
    ended at 45 deg under a supervisor whose threshold was 50 deg, so 26.5 kg is SL 0 (45 is not > 50),
    not the SL 4 the default 40 deg would give; attempt 4, recorded with 40 deg, is SL 3 at 24 kg."""
    rows = RECORD.splitlines()
    rows[4] = rows[4].replace(",bags/attempt_0004", ",bags/attempt_0004,abc,40.000")
    rows[5] = rows[5].replace(",bags/attempt_0005", ",bags/attempt_0005,abc,50.000")
    (tmp_path / "attempts.csv").write_text("\n".join(rows) + "\n")
    rc, out, err = run(attempt_mass_main, ["26.5", "--run-dir", str(tmp_path), "--attempt", "5"])
    assert rc == 0, err
    assert "success_level=0" in out and "success=false" in out, out
    assert "recorded without its pitch threshold" not in out, out
    rc, out, err = run(attempt_mass_main, ["24", "--run-dir", str(tmp_path), "--attempt", "4"])
    assert rc == 0 and "success_level=3" in out and "success=true" in out, out
    back = {r.attempt: r for r in read_rows(tmp_path / "attempts.csv")}
    assert (back[5].phi_thresh_deg, back[5].success_level, back[5].success) == (50.0, 0, False)


def test_offline_weighing_of_a_row_without_its_threshold_says_which_file_judged_it(tmp_path):
    """Rows written before the threshold was recorded: judged on --config's file (default: the default
    file), said; a row whose supervisor ran another file (config_hash) gets a warning naming --config."""
    from lhd_loading_ros.task.config import config_hash, load_config

    rows = RECORD.splitlines()
    rows[5] = rows[5].replace(",bags/attempt_0005", ",bags/attempt_0005,0123456789ab")
    (tmp_path / "attempts.csv").write_text("\n".join(rows) + "\n")
    assert config_hash(load_config()) != "0123456789ab"
    rc, out, err = run(attempt_mass_main, ["26.5", "--run-dir", str(tmp_path), "--attempt", "5"])
    assert rc == 0, err
    assert "success_level=4" in out, out                     # 45 deg > the default file's 40 deg
    assert "attempt 5: recorded without its pitch threshold; judged on the default parameter file's 40 deg" in out
    assert "hash 0123456789ab" in err and "pass its file with --config" in err, err
    rc, out, err = run(attempt_mass_main, ["26.5", "--run-dir", str(tmp_path), "--config", str(tmp_path / "no.yaml")])
    assert rc == 2 and "--config: cannot read parameter file" in err, err
    rc, out, err = run(attempt_mass_main, ["26.5", "--config", "config/lhd_params.yaml"])
    assert rc == 2 and "--config is for a weighing of the record" in err, err


def ros_env():
    from rosutil import unique_domain_id

    return dict(os.environ, ROS_DOMAIN_ID=str(unique_domain_id()))


@pytest.mark.parametrize("cmd", ["arm", "abort"])
def test_no_supervisor_is_exit_1_with_the_reason(cmd):
    p = subprocess.run(CLI + [cmd, "--timeout", "1", "--namespace", "/lhd_nobody"], capture_output=True, text=True,
                       env=ros_env(), timeout=60)
    assert p.returncode == 1
    assert f"no supervisor: service /lhd_nobody/{cmd} not available after 1 s" in p.stderr, p.stderr
    assert "Traceback" not in p.stderr


def test_mass_without_a_supervisor_is_exit_1():
    p = subprocess.run(CLI + ["mass", "20", "--timeout", "1", "--namespace", "/lhd_nobody"], capture_output=True,
                       text=True, env=ros_env(), timeout=60)
    assert p.returncode == 1 and "no supervisor: nothing on /lhd_nobody/episode after 1 s" in p.stderr, p.stderr


def test_module_usage():
    p = subprocess.run(CLI, capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "lhd attempts RUN_DIR" in p.stdout


def test_the_newest_status_is_the_last_heard_of_equal_stamps_and_a_restart_names_the_unweighed_attempt(run_dir):
    """A review (2026-11-29, twelfth session): a supervisor on sim time without /clock stamps every status 0,
    and `lhd attempt mass` took the oldest of its latched history (its confirmation then never came); a
    supervisor restarted on the same run directory says idle, and the refusal did not say how to weigh the
    attempt its predecessor left unweighed."""
    from lhd_loading_ros.cli.attempts import _newest, _unweighed_hint

    hist = [{"episode": "1", "state": "running", "stamp_ns": "0"}, {"episode": "1", "state": "timeout", "stamp_ns": "0"},
            {"episode": "1", "state": "timeout", "stamp_ns": "0", "loaded_mass": "23.4"}]
    assert _newest(hist) is hist[2]
    stamped = [{"stamp_ns": "30"}, {"stamp_ns": "50"}, {"stamp_ns": "40"}]
    assert _newest(stamped) is stamped[1]                       # stamps rule where they differ
    hint = _unweighed_hint(str(run_dir))                         # RECORD: attempt 5 ended (success), no mass
    assert "attempt 5" in hint and "lhd attempt mass KG --attempt 5" in hint
    (run_dir / "attempts.csv").write_text("\n".join(RECORD.splitlines()[:5]) + "\n")   # attempts 1-4: all weighed
    assert _unweighed_hint(str(run_dir)) == "" and _unweighed_hint(str(run_dir / "nowhere")) == ""


def test_a_duplicated_attempt_stops_the_table_and_the_weighing(run_dir):
    """A review (2026-11-30): a second row for attempt 2 made `lhd attempts` count it twice, and `lhd attempt
    mass --attempt 2 --run-dir` weighed the first, wrote one row for both and said it 'replaced' a mass."""
    p = run_dir / "attempts.csv"
    lines = RECORD.splitlines()
    p.write_text("\n".join(lines + [lines[2].replace(",25.0,", ",15.0,")]) + "\n")
    before = p.read_bytes()
    rc, out, err = run(attempts_main, [str(run_dir), "--json"])
    assert rc == 1 and out == "" and "attempt 2 on lines 3 and 8" in err, err
    rc, out, err = run(attempt_mass_main, ["30", "--run-dir", str(run_dir), "--attempt", "2"])
    assert rc == 1 and "replaced" not in out and "attempt 2 on lines 3 and 8" in err, (out, err)
    assert p.read_bytes() == before


def test_a_hand_edited_mass_is_counted_as_its_numbers_say(run_dir):
    """A review (2026-11-30): attempt 2's mass edited 25.0 -> 15.0 with success=true left: it was still counted
    a success with 15 kg. The table counts it as judged again and says so above it."""
    p = run_dir / "attempts.csv"
    p.write_text(RECORD.replace(",end zone,25.0,", ",end zone,15.0,"))
    rc, out, _ = run(attempts_main, [str(run_dir)])
    assert rc == 0
    assert "WARNING: attempt 2: the record says success (SL 3), its numbers (15.00 kg) give no success (SL 0)" in out
    mass = [l.split() for l in out.splitlines() if l.startswith("Material loaded")][0]
    assert mass == ["Material", "loaded", "[kg]", "15", "23.00±0.00"]          # attempt 1 only
    rc, out, _ = run(attempts_main, [str(run_dir), "--json"])
    d = json.loads(out)
    assert [j["attempt"] for j in d["rejudged"]] == [2]
    assert next(c for c in d["cells"] if c["controller"] == "rld")["successes"] == 1


def test_a_decimal_comma_is_named(run_dir):
    p = run_dir / "attempts.csv"
    p.write_text(RECORD.replace(",end zone,25.0,", ",end zone,25,0,"))
    rc, _, err = run(attempts_main, [str(run_dir)])
    assert rc == 1 and "line 3: 25,0 reads as two fields (a decimal comma?): write 25.0" in err, err
