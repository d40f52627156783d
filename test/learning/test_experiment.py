"""`lhd experiment paper`: the grid, the told slope, and a small study end to end (a real process
pool, the real simulator and the shipped actors)."""
PARALLEL_SAFE = True   # lhd experiment runs that only compute (test/conftest.py)

import csv
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from lhd_loading_ros.learning import experiment as ex


def test_grid_gives_every_controller_the_same_piles():
    jobs = ex.grid(("rld", "tampier"), (15.0, 30.0), ("homogeneous",), (-15.0, 0.0, 15.0), episodes=3, seed=10)
    table_a = [j for j in jobs if j.table == "controllers"]
    assert len(table_a) == 2 * 2 * 1 * 3
    seeds = {c: sorted(j.seed for j in table_a if j.controller == c) for c in ("rld", "tampier")}
    assert seeds["rld"] == seeds["tampier"] and len(set(seeds["rld"])) == 6
    table_b = [j for j in jobs if j.table == "slope_error"]
    assert {j.controller for j in table_b} == {"rld", "tampier"}            # the heuristic reads the told end zone
    assert len(table_b) == 2 * 2 * 3 * 3
    tb = {c: sorted(j.seed for j in table_b if j.controller == c) for c in ("rld", "tampier")}
    assert tb["rld"] == tb["tampier"]                                      # the same piles for both
    only = ex.grid(("scripted", "rlc"), (15.0,), ("homogeneous",), (0.0, 5.0), episodes=2)
    assert {j.controller for j in only if j.table == "slope_error"} == {"rlc"}   # scripted reads neither
    assert {(j.slope_deg, j.told_deg) for j in table_b} >= {(15.0, 30.0), (30.0, 15.0)}   # the paper's two cases
    assert all(j.told_deg == j.slope_deg for j in table_a)
    with pytest.raises(ValueError, match="unknown controller 'ppo'"):
        ex.grid(("ppo",))


def test_the_told_slope_is_the_lidars_estimate_alpha_and_zones():
    """A 15 deg pile told 30 deg in table (b): alpha is the told slope and the zones are the 30 deg
    wedge's (the end-zone node's, from the estimate): the attempt's d_end measures to the told
    x_max (1.299 -> 0.885 m at 1,880 kg/m^3: by the ratio sqrt(tan 15 / tan 30) = 0.681)."""
    from lhd_loading_ros.policy.actor_file import default_policy_dir
    ex._setup(None, {"rld": str(default_policy_dir("rld"))})   # what each pool worker gets
    job = ex.Job("slope_error", "rld", 15.0, 30.0, "homogeneous", 77)
    row = ex.run_job(job)                       # the real actor, simulator and zones
    assert row["told_deg"] == 30.0 and 0.0 < row["loaded_kg"] < 60.0
    env = ex._env("rld")
    assert env.zones_from_estimate and env.zones_from == "estimate"
    k = math.sqrt(math.tan(math.radians(15.0)) / math.tan(math.radians(30.0)))
    assert env.zones.x_max == pytest.approx(env.sim.zones.x_max * k)
    assert env.zones.x_cutoff == pytest.approx(0.68 / math.tan(math.radians(30.0)) - 0.1)
    # no error: the pile's own zones
    ex.run_job(ex.Job("slope_error", "rld", 15.0, 15.0, "homogeneous", 77))
    assert env.zones_from == "pile" and env.zones == env.sim.zones


def test_the_told_slope_changes_only_the_observed_alpha():
    from lhd_sim_node.env import LhdLoadingEnv
    env = LhdLoadingEnv("rld")
    obs, _ = env.reset(seed=4, options={"slope_deg": 20.0, "material": "homogeneous"})
    same = ex.told_observation(obs, math.radians(20.0), env.p)
    assert np.allclose(same, obs, atol=1e-6)
    told = ex.told_observation(obs, math.radians(30.0), env.p)
    assert np.array_equal(told[:-1], obs[:-1])
    assert told[-1] == pytest.approx(1.0)                                   # 30 deg: the top of [15, 30]
    assert ex.told_observation(obs, math.radians(0.0), env.p)[-1] == pytest.approx(-1.0)   # outside: as it is


def test_a_small_study_end_to_end(tmp_path):
    out = tmp_path / "exp"
    p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "experiment", "paper", "--episodes", "1",
                        "--jobs", "2", "--controllers", "rld,tampier", "--slopes", "20", "--materials", "homogeneous",
                        "--errors", "0,15", "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    assert "Success rate [%]" in p.stdout and "| 15 | 30 | +15 |" in p.stdout
    # into a pipe the progress is whole lines, no carriage returns (a review: a log got one line of thousands)
    bars = [ln for ln in p.stderr.splitlines() if ln.startswith("lhd experiment paper [")]
    assert "\r" not in p.stderr and 1 <= len(bars) <= 11 and bars[-1].split("] ")[1].startswith("10/10 attempts"), bars
    rows = list(csv.DictReader((out / "attempts.csv").open()))
    assert len(rows) == 2 + 2 * 2 * 2                      # table (a): 2 controllers; (b): both, 2 piles x 2 errors
    for r in rows:
        assert r["success"] in ("True", "False") and 0.0 <= float(r["loaded_kg"]) < 60.0
        assert 0.0 < float(r["elapsed_s"]) <= ex.TIME_LIMIT_S + 1e-9
    # strict JSON: a metric over no successful attempt is null, not a bare NaN (a review)
    summary = json.loads((out / "summary.json").read_text(), parse_constant=lambda c: pytest.fail(f"bare {c}"))
    assert summary["attempts"] == 10 and summary["time_limit_s"] == 10.0
    # the paired table: RLD against the heuristic on the one pile they share, its masses from attempts.csv
    (pr,) = [r for r in summary["paired_table"] if r["slope_deg"] == "all"]
    a = {r["controller"]: r for r in rows if r["table"] == "controllers"}
    assert pr["other"] == "tampier" and pr["pairs"] == 1
    assert pr["mass_diff_all_kg"] == pytest.approx(float(a["rld"]["loaded_kg"]) - float(a["tampier"]["loaded_kg"]))
    assert "RLD against the other controllers on the same piles" in p.stdout
    for f in ("table_controllers.md", "table_controllers.csv", "table_slope_error.md", "table_slope_error.csv",
              "table_paired.md", "table_paired.csv", "mass_vs_time.png", "tip_trajectories.png", "slope_error.png"):
        assert (out / f).stat().st_size > 0, f
    # the no-error rows are their own baseline: a mass change of 0 %
    err = list(csv.DictReader((out / "table_slope_error.csv").open()))
    assert {float(r["mass_change_pct"]) for r in err if float(r["error_deg"]) == 0.0} == {0.0}
    # a told slope outside the config's 15-30 deg (a 30 deg pile told 45) is marked: the nodes refuse it
    md = (out / "table_slope_error.md").read_text()
    assert "| RLD | 30 | 45 * | +15 |" in md and "| RLD | 15 | 30 | +15 |" in md and "| RLD | 15 | 15 * |" not in md
    assert "the policy node refuses such an estimate" in md and "(15-30 deg)" in md
    assert "| TAMPIER | 30 | 45 | +15 |" in md        # the heuristic has no trained range: no mark
    # bad input: one line, exit 2
    p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "experiment", "paper", "--slopes", "20,x",
                        "--out", str(tmp_path / "bad")], capture_output=True, text=True, timeout=60)
    assert p.returncode != 0 and "expected comma-separated numbers" in p.stderr


def test_slope_error_table_marks_told_slopes_outside_the_trained_range():
    rows = [{"controller": "rld", "slope_deg": a, "told_deg": t, "error_deg": t - a, "attempts": 2, "success_rate": 1.0,
             "loaded_kg": 30.0, "loaded_kg_sd": 0.0, "mass_change_pct": 0.0}
            for a, t in ((15.0, 0.0), (15.0, 10.0), (15.0, 35.0), (30.0, 35.0), (30.0, 35.5))]
    md = ex.markdown_slope_error(rows, (10.0, 35.0))
    marked = [ln.split(" | ")[2] for ln in md.splitlines() if ln.startswith("| RLD")]
    assert marked == ["0 *", "10", "35", "35", "35.5 *"]
    assert "(10-35 deg)" in md
    assert "*" not in ex.markdown_slope_error(rows[1:4], (10.0, 35.0))     # none outside: no mark, no note
    assert "*" not in ex.markdown_slope_error(rows)                         # no range given: as before


def test_the_teacher_is_the_demonstrations_maneuver(cfg):
    """The `teacher` controller drives the training demonstrations' maneuver at the middle of their
    crowd range: its attempt equals one driven here with scripted_action at the told zones' x_min
    (no slope error here: the pile's), crowd (0.5 + 0.75) / 2, pre-curl 0.3 and the wheels stopped
    within 0.2 m of the end zone's far side (config/lhd_params.yaml's told teacher), step for step;
    on a 15 deg pile it loads over 30 kg."""
    from lhd_sim_node.env import LhdLoadingEnv
    from lhd_sim_node.scripted import scripted_action

    assert ex.teacher_setting(cfg) == (0.625, 0.3, True, 0.2, 0.0, 0.0)
    ex._setup(None, {})
    job = ex.Job("controllers", "teacher", 15.0, 15.0, "homogeneous", 3_150_000)   # the first pile of the 15 deg cell
    row = ex.run_job(job)
    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=job.seed, options={"slope_deg": 15.0, "material": "homogeneous"})
    while True:
        z = env.zones
        _, _, term, trunc, info = env.step(scripted_action(env.state, z.x_min, crowd=0.625, pre_curl=0.3,
                                                           lift_on_drift=True, end_zone=(z.x_max, z.z_min),
                                                           end_zone_stop=0.2))
        if term or trunc or env.steps >= 100:
            break
    assert row["loaded_kg"] == pytest.approx(env.sim.loaded_mass, abs=1e-9)
    assert row["elapsed_s"] == pytest.approx(env.steps * env.p.control_dt)
    assert row["success"] and row["loaded_kg"] > 30.0


def _attempt(controller, slope, seed, success, kg, t=4.0, front=0.0, rear=50.0, material="homogeneous"):
    return {"table": "controllers", "controller": controller, "slope_deg": slope, "told_deg": slope, "material": material,
            "seed": seed, "success": success, "loaded_kg": kg, "elapsed_s": t, "front_drift_pct": front,
            "rear_drift_pct": rear}


def test_the_paired_table_compares_the_same_piles_where_both_succeeded():
    rows = [
        # 20 deg, three piles: both succeed on seeds 1 and 2; the heuristic fails on seed 3
        _attempt("rld", 20.0, 1, True, 35.0, t=4.0, front=1.0), _attempt("tampier", 20.0, 1, True, 41.0, t=10.0, front=20.0),
        _attempt("rld", 20.0, 2, True, 33.0, t=3.0, front=2.0), _attempt("tampier", 20.0, 2, True, 40.0, t=9.0, front=16.0),
        _attempt("rld", 20.0, 3, True, 36.0), _attempt("tampier", 20.0, 3, False, 44.0),
        # 30 deg, one pile, RLD fails: no successful pair there
        _attempt("rld", 30.0, 4, False, 12.0), _attempt("tampier", 30.0, 4, True, 42.0),
        # a heuristic attempt on a pile RLD never saw, and another material: neither pairs with the 20 deg cell
        _attempt("tampier", 20.0, 9, True, 10.0), _attempt("rld", 20.0, 1, True, 99.0, material="nonhomogeneous"),
        {"table": "slope_error", "controller": "rld", "slope_deg": 20.0, "told_deg": 35.0, "material": "homogeneous",
         "seed": 1, "success": True, "loaded_kg": 0.0, "elapsed_s": 1.0, "front_drift_pct": 0.0, "rear_drift_pct": 0.0},
    ]
    out = ex.paired_comparison(rows, seed=1)
    cell = {(r["material"], r["slope_deg"]): r for r in out if r["other"] == "tampier"}
    c20 = cell[("homogeneous", 20.0)]
    assert c20["pairs"] == 3 and c20["both_successful"] == 2
    assert c20["loaded_kg_diff"] == pytest.approx(((35 - 41) + (33 - 40)) / 2)          # -6.5 kg, by hand
    assert c20["loaded_kg_ref"] == pytest.approx(34.0) and c20["loaded_kg_other"] == pytest.approx(40.5)
    assert c20["elapsed_s_diff"] == pytest.approx(-6.0) and c20["front_drift_pct_diff"] == pytest.approx(-16.5)
    # two pairs (-6, -7): every resample's mean lies in [-7, -6]; the interval is inside and not a point
    assert -7.0 <= c20["loaded_kg_diff_lo"] < c20["loaded_kg_diff_hi"] <= -6.0
    assert c20["mass_diff_all_kg"] == pytest.approx(((35 - 41) + (33 - 40) + (36 - 44)) / 3)
    c30 = cell[("homogeneous", 30.0)]
    assert c30["pairs"] == 1 and c30["both_successful"] == 0 and math.isnan(c30["loaded_kg_diff"])
    assert c30["mass_diff_all_kg"] == pytest.approx(12.0 - 42.0)
    every = cell[("homogeneous", "all")]
    assert every["pairs"] == 4 and every["both_successful"] == 2 and every["loaded_kg_diff"] == pytest.approx(-6.5)
    assert ("nonhomogeneous", 20.0) not in cell            # the heuristic has no nonhomogeneous attempts
    # one pair: a mean, no interval; the markdown says so with a dash
    one = ex.paired_comparison([rows[0], rows[1]])
    (r1,) = [r for r in one if r["slope_deg"] == 20.0]
    assert r1["loaded_kg_diff"] == pytest.approx(-6.0) and math.isnan(r1["loaded_kg_diff_lo"])
    md = ex.markdown_paired(out)
    assert "| tampier | homogeneous | 20 | 3 (2) | 34.0 / 40.5 | -6.5 [" in md
    assert "| tampier | homogeneous | 30 | 1 (0) | - / - | - |" in md
    # deterministic for a seed; without the reference controller, nothing to compare
    assert ex.paired_comparison(rows, seed=1) == out
    assert ex.paired_comparison([r for r in rows if r["controller"] != "rld"]) == []


def test_a_stress_case_reaches_every_controller_on_the_same_piles(cfg):
    """`lhd experiment paper --stress light`: every controller's attempt k of a cell meets the same pile
    under the case's k-th conditions; the pile's gravel is then in the light band (the randomisation
    section's lowest 100 kg/m^3, dry loose gravel), not in the nominal pile range."""
    from dataclasses import replace

    jobs = ex.grid(("tampier", "teacher"), (20.0,), ("homogeneous",), (), episodes=1, seed=3_000_000, stress="light")
    assert len(jobs) == 2 and {j.stress for j in jobs} == {"light"} and {j.attempt for j in jobs} == {0}
    ex._setup(None, {})
    rows = [ex.run_job(j) for j in jobs]
    lo = cfg["randomization"]["density_min"]
    dens = [r["pile_density"] for r in rows]
    assert dens[0] == dens[1]                                                # the same pile for both
    assert 0.97 * lo <= dens[0] <= 1.03 * (lo + 100.0)                      # +-5 % voxel jitter about the draw
    nominal = ex.run_job(replace(jobs[0], stress=None))
    assert 0.97 * cfg["pile"]["density_min"] <= nominal["pile_density"] <= 1.03 * cfg["pile"]["density_max"]
    assert rows[0]["stress"] == "light" and nominal["stress"] is None        # the CSV says which
    with pytest.raises(ValueError, match="unknown stress case 'wet'"):
        ex.grid(("rld",), stress="wet")


def test_a_rough_face_read_beyond_the_trained_range_is_refused_for_the_rl_actors_only(cfg):
    """`--stress rough` on 30 deg piles: the LiDAR scans one slice of the rough face, whose slope can exceed the
    main job's 15-30 deg. Those RL attempts are refused, as the policy node refuses them (lhd eval counts them
    so); the heuristic on the same piles runs. Which ones: computed here from the environment's own slice slope."""
    from lhd_sim_node.env import LhdLoadingEnv
    from lhd_loading_ros.task.randomization import stress_conditions

    from lhd_loading_ros.policy.actor_file import default_policy_dir

    ex._setup(None, {"rld": str(default_policy_dir("rld"))})   # the main job's actor, trained on 15-30 deg
    env = LhdLoadingEnv("rld")
    seen, rows = set(), []
    for k in range(8):
        job = ex.Job("controllers", "rld", 30.0, 30.0, "homogeneous", 3_000_000 + k, stress="rough", attempt=k)
        env.reset(seed=job.seed, options={"slope_deg": 30.0, "material": "homogeneous",
                                          "conditions": stress_conditions("rough", k, env.cfg)})
        beyond = env.told_slope_deg > 30.0 + 1e-6
        row = ex.run_job(job)
        rows.append(row)
        assert row["refused"] is beyond and row["told_deg"] == 30.0
        if beyond:
            assert not row["success"] and row["loaded_kg"] == 0.0 and row["elapsed_s"] == 0.0
        else:
            assert row["elapsed_s"] > 0.0
        seen.add(beyond)
        if k == 0 or beyond:                       # the heuristic is no actor: never refused
            assert ex.run_job(ex.Job("controllers", "tampier", 30.0, 30.0, "homogeneous", job.seed, stress="rough",
                                     attempt=k))["refused"] is False
    assert seen == {True, False}, "8 rough piles all read on one side of 30 deg: pick other seeds"
    every = next(r for r in ex.summarize_controllers(rows) if r["slope_deg"] == "all")
    n = sum(r["refused"] for r in rows)
    assert every["refused"] == n and every["success_rate"] <= (8 - n) / 8
    assert f"RLD {n} attempts whose told slope" in ex.markdown_controllers(ex.summarize_controllers(rows))


def test_the_end_zone_nodes_zones_reach_every_controller(cfg, params):
    """`lhd experiment paper --zones end-zone-node`: every attempt is judged, and the heuristic steered,
    by the end-zone node's wedge at the nominal density (1,880 kg/m^3), not the light pile's own end
    zone: on a 20 deg pile x_max = sqrt(2 x 170 / (1880 x 0.4 x tan 20)) = 1.1148 m by hand, while
    the light pile's own 170 kg lie about sqrt(1880 / 1550) = 1.10 times farther."""
    jobs = ex.grid(("tampier", "teacher"), (20.0,), ("homogeneous",), (), episodes=1, seed=3_000_000, stress="light")
    ex._setup(None, {}, "end-zone-node")
    node = [ex.run_job(j) for j in jobs]
    ex._setup(None, {}, "pile")
    own = [ex.run_job(j) for j in jobs]
    for n, o in zip(node, own):
        assert n["zones_from"] == "wedge at nominal density" and o["zones_from"] == "pile"
        assert n["x_max"] == pytest.approx(1.1148, abs=5e-4)
        assert o["x_max"] == pytest.approx(1.1148 * math.sqrt(1880.0 / o["pile_density"]), abs=0.02)
    with pytest.raises(ValueError, match="zones 'lidar': expected one of pile, end-zone-node"):
        ex.run(jobs, 1, zones="lidar")
    # the node's density set by hand (--zones-density): only with the node's zones, and a density it takes
    with pytest.raises(ValueError, match="--zones-density 1550 is the end-zone node's density: it needs --zones end-zone-node"):
        ex.run(jobs, 1, zones="pile", zones_density=1550.0)
    with pytest.raises(ValueError, match="--zones-density 40: bulk density 40 kg/m\\^3 outside"):
        ex.run(jobs, 1, zones="end-zone-node", zones_density=40.0)
    ex._setup(None, {}, "end-zone-node", 1550.0)
    set_ = ex.run_job(jobs[0])
    assert set_["x_max"] == pytest.approx(1.114545 * math.sqrt(1880.0 / 1550.0), abs=2e-6)
