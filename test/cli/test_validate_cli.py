"""`lhd validate physics --quick --json`: the figures of issue 13 come out, finite, with the plots.
(The thresholds those figures must meet are tested where the physics lives: test_fee_face.py,
test_bucket_body.py, test_drift_tempo.py, test_bucket_capacity.py; this is the harness's smoke test.)"""
import json
import math
from pathlib import Path

from lhd_loading_ros.cli.main import main


def _finite(v):
    return isinstance(v, (int, float)) and math.isfinite(v)


def test_validate_physics_quick_json_and_plots(tmp_path, capsys):
    rc = main(["validate", "physics", "--quick", "--json", "--plots", str(tmp_path)])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res) >= {"resistance", "sweeps", "capacity", "drift", "scripted", "naive", "plots", "wall_s"}
    # 1. resistance vs slope, next to the reference
    r1 = res["resistance"]
    for mode in ("equal_insertion", "fixed_depth"):
        assert len(r1[mode]) >= 3 and isinstance(r1[mode + "_monotonic"], bool)
        for row in r1[mode]:
            assert _finite(row["sim_N"]) and row["sim_N"] >= 0.0
            assert _finite(row["ref_N"]) and row["ref_N"] > 0.0 and _finite(row["depth_m"])
    assert [r["slope_deg"] for r in r1["fixed_depth"]][0] == 0.0          # the flat case
    # 2. curl and lift sweeps: at least the buried start is measured and referenced
    case = res["sweeps"]["cases"][0]
    for motion in ("curl", "lift"):
        b0 = case[motion]["bins"][0]
        assert b0["angle_deg"] == 0.0 and _finite(b0["sim_Nm"]) and _finite(b0["ref_Nm"]) and b0["ref_Nm"] > 0.0
        assert case[motion]["start"]["lip_depth"] > 0.0
    # 3. capacity
    cp = res["capacity"]
    assert cp["struck_L"] > 0 and cp["heaped_iso_L"] > cp["struck_L"] and _finite(cp["struck_kg"])
    assert all(_finite(b["ref_L"]) for b in cp["by_pitch"])
    assert cp["handbook_fill"] == [0.85, 0.90] and _finite(cp["table_level_share_of_rating"])
    hf = res["heuristic_fill"]          # the heuristic's delivered fill, next to the handbook's
    assert len(hf["attempts"]) >= 2 and hf["handbook"] == [0.85, 0.90] and isinstance(hf["within_handbook"], bool)
    assert all(_finite(a["loaded_kg"]) and a["loaded_kg"] >= 0.0 for a in hf["attempts"])
    # 4. drift vs timestep
    assert len(res["drift"]["rows"]) >= 2
    assert all(0.0 <= r[k] <= 100.0 for r in res["drift"]["rows"] for k in ("front_pct", "rear_pct"))
    # 5. scripted attempts, 6. naive controllers
    for mat in ("homogeneous", "nonhomogeneous"):
        assert _finite(res["scripted"][mat]["time_s"]) and _finite(res["scripted"][mat]["mass_kg"])
    for k in ("push_only", "curl_lift_no_drive", "random"):
        assert 0.0 <= res["naive"][k]["success_rate"] <= 1.0
    assert isinstance(res["naive"]["push_stalls_before_full"], bool)
    by = res["naive"]["push_only"]["loaded_at_end_kg_by_slope"]
    assert set(by) >= {"15", "30"} and all(_finite(v) and v >= 0.0 for v in by.values())
    # the plots
    assert len(res["plots"]) == 4
    for p in res["plots"]:
        assert Path(p).is_file() and Path(p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_validate_needs_a_subject(capsys):
    assert main(["validate"]) == 2
    assert "validate physics" in capsys.readouterr().err
