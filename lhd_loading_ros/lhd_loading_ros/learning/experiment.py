"""`lhd experiment paper`: the paper's real-world tables, run in the simulator.

(a) **Controllers x slopes x materials** (the paper's results table): every controller on 15, 20,
    25 and 30 deg piles, homogeneous and nonhomogeneous, `episodes` attempts per cell; success
    rate, and over the SUCCESSFUL attempts (as the paper reports them) loaded mass, time, front and
    rear drift, mean and standard deviation.
(b) **Slope error** (the paper's robustness table and a sweep): the RL actors (the paper's table
    has only them) and the controllers that read the end zone (`tampier`, and `teacher`, which reads
    the told zones with training.demo_told_zones and the pile's own otherwise; `scripted` reads
    neither and is left out) on 15 and 30 deg piles told a wrong slope: the observation's alpha is the told slope, and the zones are those the
    end-zone node builds from it (d_end, the end zone and the restricted zone that end the attempt;
    task/zones.zones_for_slope_estimate; before 2026-11-28 the true pile's), everything else the
    true pile: the paper's two cases (a 15 deg pile told 30, a 30 deg pile told 15) are the +15 and
    -15 deg entries of a sweep over `errors`.

Controllers: `rld`, `rlc` (the shipped actors, policies/; RLC with the deployment filter, as on the
machine), `tampier` (the Tampier-style heuristic, config/tampier.yaml), `scripted` (the fixed
maneuver of lhd_sim_node.scripted, lifting at the paper's x_midgoal) and `teacher` (the same
maneuver as the training demonstrations drive it, learning/demonstrations.py: lifting at the pile's
x_min or the first wheel drift, the bucket curled to training.demo_pre_curl first, the wheels at the
middle of [demo_crowd_min, demo_crowd_max] while lifting; it reads the simulator's state, the pile's
x_min included, which no machine-side controller has; with training.demo_told_zones the told zones
instead, and training.demo_end_zone_stop stops its wheels in the end zone). Every attempt is limited to the paper's real-world 10 s.
Each attempt has its own seed (base seed + index in the grid), so a cell is the same set of piles
for every controller; the attempts run on a process pool (`jobs`) and print their progress.

Under a named stress case (`stress`, task.randomization.stress_conditions: `--stress light` is dry,
loose gravel, the density the bucket's 30 kg rating implies) every attempt of every controller runs
under the case's conditions; attempt k of a cell gets the case's k-th conditions, so the controllers
still meet the same piles and the same departures. What the simulator applies (material, actuator
gains and dead time, the machine's placement) acts on every controller; the sensor noise acts only on
the RL actors' observations: the heuristic and the scripted maneuvers read the simulator's state.

A told slope outside the actors' trained range (15-30 deg) is given to the actor as it is, as a
wrong LiDAR estimate would be: the normalised alpha then leaves [0, 1]. The nodes refuse such a
slope; this table shows what the actor alone would do. Below the LiDAR's 5 deg the end-zone node
builds no zones; such a cell keeps the pile's own.

Writes to `out`: attempts.csv (one row per attempt), table_controllers.md/.csv,
table_slope_error.md/.csv, table_paired.md/.csv (RLD against each other controller on the same piles:
paired_comparison), mass_vs_time.png, tip_trajectories.png, slope_error.png, summary.json.
"""
from __future__ import annotations

import csv
import math
import os
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from lhd_loading_ros.learning.evaluate import zones_nominal_density
from lhd_loading_ros.task import json_out
from lhd_loading_ros.task.cores import usable_cores

CONTROLLERS = ("rld", "rlc", "tampier", "scripted", "teacher")
SLOPE_ERROR_CONTROLLERS = ("rld", "rlc", "tampier", "teacher")   # table (b): those a slope estimate reaches
SLOPES = (15.0, 20.0, 25.0, 30.0)
MATERIALS = ("homogeneous", "nonhomogeneous")
ERRORS = (-15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0)
ERROR_PILES = (15.0, 30.0)
TIME_LIMIT_S = 10.0          # the paper's real-world attempts (experimental settings)
TRACE_ATTEMPTS = 3           # attempts per (controller, 20 deg, homogeneous) cell whose tip path is kept


@dataclass(frozen=True)
class Job:
    table: str               # "controllers" or "slope_error"
    controller: str
    slope_deg: float         # the pile's true slope
    told_deg: float          # the slope in the controller's observation
    material: str
    seed: int
    trace: bool = False
    stress: str | None = None  # a named case of task.randomization.stress_conditions, or nominal
    attempt: int = 0           # k, the attempt's index in its cell: its conditions under `stress`


def grid(controllers=CONTROLLERS, slopes=SLOPES, materials=MATERIALS, errors=ERRORS, error_piles=ERROR_PILES,
         episodes: int = 10, seed: int = 3_000_000, stress: str | None = None) -> list[Job]:
    """Every attempt of both tables. Attempt k of a cell has seed seed + 1000 * cell_key + k, where
    the cell key depends on the pile only (slope, material), so all controllers meet the same piles
    (and, under `stress`, the same conditions: the case's k-th)."""
    from lhd_loading_ros.task.randomization import STRESS_CASES
    if stress is not None and stress not in STRESS_CASES:
        raise ValueError(f"unknown stress case {stress!r}; expected one of {', '.join(STRESS_CASES)}")
    for c in controllers:
        if c not in CONTROLLERS:
            raise ValueError(f"unknown controller {c!r}; expected some of {', '.join(CONTROLLERS)}")
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    jobs = []
    for c in controllers:
        for a in slopes:
            for m in materials:
                key = int(round(a)) * 10 + MATERIALS.index(m)
                for k in range(episodes):
                    jobs.append(Job("controllers", c, float(a), float(a), m, seed + 1000 * key + k,
                                    trace=(a == 20.0 and m == "homogeneous" and k < TRACE_ATTEMPTS), stress=stress,
                                    attempt=k))
    for c in (c for c in controllers if c in SLOPE_ERROR_CONTROLLERS):
        for a in error_piles:
            for e in errors:
                key = 900 + int(round(a))
                for k in range(episodes):
                    jobs.append(Job("slope_error", c, float(a), float(a + e), "homogeneous", seed + 1000 * key + k,
                                    stress=stress, attempt=k))
    return jobs


# ------------------------------------------------------------------------------ one attempt
_WORKER: dict = {}


def _setup(config, policy_dirs: dict, zones: str = "pile", zones_density: float | None = None) -> None:
    _WORKER.clear()
    _WORKER.update(config=config, policy_dirs=dict(policy_dirs), zones=zones, zones_density=zones_density)


def _env(variant: str, deploy_filter: bool = False):
    from lhd_sim_node.env import LhdLoadingEnv

    from lhd_loading_ros.task.config import load_config
    key = ("env", variant, deploy_filter)
    if key not in _WORKER:
        cfg = _WORKER.get("config")
        cfg = cfg if isinstance(cfg, dict) else load_config(cfg)
        _WORKER[key] = LhdLoadingEnv(variant, cfg, deploy_filter=deploy_filter, zones_from_estimate=True,
                                     zones_nominal_density=zones_nominal_density(_WORKER.get("zones", "pile")),
                                     zones_density=_WORKER.get("zones_density"))
    return _WORKER[key]


def _actor(controller: str):
    from lhd_loading_ros.policy.actor_file import load_policy
    key = ("actor", controller)
    if key not in _WORKER:
        _WORKER[key] = load_policy(_WORKER["policy_dirs"][controller]).actor
    return _WORKER[key]


def told_observation(obs: np.ndarray, told_rad: float, p) -> np.ndarray:
    """The observation with alpha (its last entry, normalised over [alpha_min, alpha_max] as
    task.observation does) replaced by the told slope; nothing else changes."""
    out = np.array(obs, dtype=np.float32, copy=True)
    out[-1] = (told_rad - p.alpha_min) / (p.alpha_max - p.alpha_min)
    return out


def teacher_setting(cfg: dict) -> tuple[float, float, bool, float, float, float]:
    """(crowd, pre_curl, told_zones, end_zone_stop, push_curl, late_lift) of the `teacher` controller:
    the middle of the demonstrations' crowd range, their pre-curl, the zones they read, where they stop
    the wheels and the push-curl maneuver's two settings (config training.demo_*;
    policy/teacher.TeacherSetting, which the policy node's controller:=teacher reads too)."""
    from lhd_loading_ros.policy.teacher import TeacherSetting

    return TeacherSetting.from_config(cfg).as_tuple()


def run_job(job: Job) -> dict:
    """One attempt; a row of attempts.csv (and the tip's path when job.trace)."""
    from lhd_sim_node.scripted import scripted_action

    from lhd_loading_ros.policy.tampier import TampierController, load_tampier_config
    c = job.controller
    env = _env("rlc" if c == "rlc" else "rld", deploy_filter=(c == "rlc"))
    limit = max(1, int(round(TIME_LIMIT_S / env.p.control_dt)))
    opts = {"slope_deg": job.slope_deg, "material": job.material}
    if job.stress is not None:
        from lhd_loading_ros.task.randomization import stress_conditions
        opts["conditions"] = stress_conditions(job.stress, job.attempt, env.cfg)
    if job.told_deg != job.slope_deg:
        # the told slope is the LiDAR's estimate: the environment builds the zones from it (d_end, the end
        # and restricted zones), as the end-zone node does on the machine; told_observation below puts it
        # into alpha as it is, also outside [alpha_min, alpha_max], where the environment would clip it
        from lhd_loading_ros.task.randomization import NOMINAL
        c0 = opts.get("conditions", NOMINAL)
        opts["conditions"] = replace(c0, slope_error_deg=c0.slope_error_deg + job.told_deg - job.slope_deg)
    obs, _ = env.reset(seed=job.seed, options=opts)
    profile = None
    if job.trace:
        from lhd_sim_node.sim_sensors import pile_profile
        profile = pile_profile(env.sim.pile).tolist()
    # the slope the LiDAR gives (env.told_slope_deg): the told one, plus a rough face's scanned slice under
    # --stress rough / machine (until 2026-11-29 the RL actors were told job.told_deg there, while the zones
    # were built from the slice's slope)
    told = math.radians(env.told_slope_deg)
    if c == "teacher":
        from lhd_loading_ros.learning.demonstrations import demo_action
        teacher = teacher_setting(env.cfg)
        # the training's drift confirmation (training.demo_drift_confirm; 1: every flag at once)
        confirm = int(env.cfg["training"].get("demo_drift_confirm", 1))
    if c == "tampier":
        if ("tampier",) not in _WORKER:
            _WORKER[("tampier",)] = TampierController(load_tampier_config(), env.p)
        ctl = _WORKER[("tampier",)]
        ctl.reset()
        z = env.zones      # what the end-zone node gives the controller (the estimate's, with a slope error)
        end_zone = (z.x_min, z.x_max, z.z_min)
    path = [(env.state.x_shovel, env.state.z_shovel)]
    lo, hi = math.degrees(env.p.alpha_min), math.degrees(env.p.alpha_max)
    # an RL actor told a slope outside its trained range only through the stress (a rough face's slice) is
    # refused by the policy node and not armed by the supervisor: not run, a failure that loads nothing (as
    # lhd eval counts it). Table (b)'s rows told such a slope on purpose (marked *) still run: what the actor
    # alone does with it
    refused = c in ("rld", "rlc") and bool(env.slope_refusal) and lo - 1e-9 <= job.told_deg <= hi + 1e-9
    while not refused:
        if c in ("rld", "rlc"):
            a = np.clip(np.asarray(_actor(c)(told_observation(obs, told, env.p)), dtype=np.float64), -1.0, 1.0)
            obs, _, term, trunc, info = env.step(a)
        elif c == "scripted":
            obs, _, term, trunc, info = env.step(scripted_action(env.measured_state, env.p.x_midgoal, lift_on_drift=True))
        elif c == "teacher":
            obs, _, term, trunc, info = env.step(demo_action(env, *teacher, measured=True, drift_confirm=confirm))
        else:
            obs, _, term, trunc, info = env.step_actuator(np.asarray(ctl.step(env.measured_state, end_zone)))
        path.append((env.state.x_shovel, env.state.z_shovel))
        if term or trunc:
            r = info["episode_result"]
            break
        if env.steps >= limit:
            r = env.result("timeout", truncated=True)
            break
    if refused:
        r = env.refused_result()
    row = {**asdict(job), "refused": refused, "success": bool(r.success), "success_level": int(r.success_level),
           "reached_end_zone": bool(r.reached_end_zone), "failed": bool(r.failed), "timeout": bool(r.truncated),
           "loaded_kg": float(r.loaded), "elapsed_s": float(r.elapsed_s), "front_drift_pct": float(r.front_drift_pct),
           "rear_drift_pct": float(r.rear_drift_pct), "phi_final_deg": math.degrees(r.phi_final),
           "pile_density": float(np.median(env.sim.pile.density)),   # the gravel's (rocks are a few voxels)
           "x_max": float(env.zones.x_max), "zones_from": env.zones_from}   # the end zone the attempt was judged by
    row.pop("trace")
    if job.trace:
        row["path"] = path
        row["profile"] = profile
    return row


# ------------------------------------------------------------------------------ the study
def run(jobs: list[Job], jobs_n: int = 0, config=None, policy_dirs: dict | None = None, progress=sys.stderr,
        zones: str = "pile", zones_density: float | None = None) -> list[dict]:
    """Run every attempt on a pool of `jobs_n` processes (0: the machine's cores); rows in job order.
    zones: "pile" or "end-zone-node" (ZONES); zones_density: the end-zone node's `density` (kg/m^3; None: the
    config's nominal), with "end-zone-node" only."""
    import multiprocessing as mp

    zones_nominal_density(zones, zones_density)       # wrong zones before the pool
    from lhd_loading_ros.policy.actor_file import default_policy_dir
    dirs = {v: str(default_policy_dir(v)) for v in ("rld", "rlc")}
    dirs.update(policy_dirs or {})
    from lhd_loading_ros.policy.actor_file import load_policy
    from lhd_loading_ros.task.config import load_config
    cfg = config if isinstance(config, dict) else load_config(config)
    if jobs_n < 0:
        raise ValueError(f"--jobs must be >= 0 (0: one per core), got {jobs_n}")
    ep = cfg["paper"]["episode"]
    lo, hi = ep["alpha_min_deg"], ep["alpha_max_deg"]
    outside = sorted({j.slope_deg for j in jobs if not lo <= j.slope_deg <= hi})
    if outside:      # before the pool: the environment would refuse each pile with its own option name
        where = "--slopes" if any(j.table == "controllers" and j.slope_deg in outside for j in jobs) else \
            "the slope-error table's piles"
        raise ValueError(f"{where}: {', '.join(f'{a:g}' for a in outside)} deg outside the piles of the parameter file "
                         f"({lo:g}-{hi:g} deg, paper.episode.alpha_min_deg / alpha_max_deg)")
    for c in sorted({j.controller for j in jobs} & {"rld", "rlc"}):
        pol = load_policy(dirs[c]).check_config(cfg)    # before the pool: an actor trained with another scaling is refused
        if pol.variant != c:       # an RLC actor run as RLD (or back) would be tabled under the wrong name
            raise ValueError(f"--{c} {dirs[c]} is an {pol.variant.upper()} actor, not {c.upper()}: expected a policy "
                             f"folder of the {c.upper()} variant (its policy.json says variant {c!r})")
    n = jobs_n or usable_cores()
    rows: list = [None] * len(jobs)
    t0 = time.monotonic()

    # on a terminal one line redrawn in place; into a file or pipe a line at each tenth (a review: a log file got
    # one line of thousands of carriage returns)
    tty = progress is not None and getattr(progress, "isatty", lambda: False)()

    def tick(done):
        if progress is not None:
            if not tty and done != len(jobs) and int(10 * done / len(jobs)) == int(10 * (done - 1) / len(jobs)):
                return
            el = time.monotonic() - t0
            eta = el / done * (len(jobs) - done) if done else float("nan")
            bar = "#" * int(30 * done / len(jobs))
            progress.write(f"{'' if not tty else chr(13)}lhd experiment paper [{bar:<30}] {done}/{len(jobs)} attempts, "
                           f"{el:.0f} s, about {eta:.0f} s left {'' if tty else chr(10)}")
            progress.flush()

    if n == 1:
        _setup(config, dirs, zones, zones_density)
        for i, j in enumerate(jobs):
            rows[i] = run_job(j)
            tick(i + 1)
    else:
        with mp.get_context("spawn").Pool(n, initializer=_setup, initargs=(config, dirs, zones, zones_density)) as pool:
            for done, (i, row) in enumerate(pool.imap_unordered(_indexed, list(enumerate(jobs)), chunksize=1), 1):
                rows[i] = row
                tick(done)
    if progress is not None and tty:
        progress.write("\n")
    return rows


def _indexed(item):
    i, job = item
    return i, run_job(job)


def _stat(xs) -> tuple[float, float]:
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    if not xs:
        return math.nan, math.nan
    return float(np.mean(xs)), float(np.std(xs, ddof=1)) if len(xs) > 1 else 0.0


def summarize_controllers(rows: list[dict]) -> list[dict]:
    """Per (controller, material, slope): success rate over all attempts; mass, time, drift over
    the successful ones (the paper's convention); plus a row per (controller, material) over slopes."""
    out = []
    rs = [r for r in rows if r["table"] == "controllers"]
    keys = sorted({(r["controller"], r["material"]) for r in rs}, key=lambda k: (CONTROLLERS.index(k[0]), k[1]))
    for c, m in keys:
        slopes = sorted({r["slope_deg"] for r in rs if r["controller"] == c and r["material"] == m})
        for a in [*slopes, None]:
            cell = [r for r in rs if r["controller"] == c and r["material"] == m and (a is None or r["slope_deg"] == a)]
            ok = [r for r in cell if r["success"]]
            row = {"controller": c, "material": m, "slope_deg": "all" if a is None else a, "attempts": len(cell),
                   "success_rate": len(ok) / len(cell), "refused": sum(1 for r in cell if r.get("refused"))}
            for k in ("loaded_kg", "elapsed_s", "front_drift_pct", "rear_drift_pct"):
                row[k], row[k + "_sd"] = _stat([r[k] for r in ok])
            out.append(row)
    return out


def summarize_slope_error(rows: list[dict]) -> list[dict]:
    """Per (controller, pile, error): success rate and mean loaded mass over all attempts (a failed
    attempt's load counts: the table asks how much material a wrong slope costs), and the mass's
    change against the same pile without error."""
    rs = [r for r in rows if r["table"] == "slope_error"]
    out = []
    for c in [c for c in CONTROLLERS if any(r["controller"] == c for r in rs)]:
        for a in sorted({r["slope_deg"] for r in rs}):
            cells = {}
            for e in sorted({r["told_deg"] - r["slope_deg"] for r in rs if r["slope_deg"] == a}):
                cell = [r for r in rs if r["controller"] == c and r["slope_deg"] == a
                        and abs(r["told_deg"] - a - e) < 1e-9]
                if cell:
                    cells[e] = cell
            base = np.mean([r["loaded_kg"] for r in cells[0.0]]) if 0.0 in cells else math.nan
            for e, cell in cells.items():
                mass, sd = _stat([r["loaded_kg"] for r in cell])
                out.append({"controller": c, "slope_deg": a, "told_deg": a + e, "error_deg": e, "attempts": len(cell),
                            "success_rate": float(np.mean([r["success"] for r in cell])), "loaded_kg": mass,
                            "loaded_kg_sd": sd, "mass_change_pct": 100.0 * (mass / base - 1.0) if base > 0 else math.nan})
    return out


PAIRED_METRICS = ("loaded_kg", "elapsed_s", "front_drift_pct", "rear_drift_pct")
BOOTSTRAP_RESAMPLES = 10_000


def _bootstrap_mean_ci(d: np.ndarray, rng: np.random.Generator, level: float = 0.95) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of `d` (resampling the pairs)."""
    if len(d) < 2:
        return math.nan, math.nan
    means = d[rng.integers(0, len(d), size=(BOOTSTRAP_RESAMPLES, len(d)))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def paired_comparison(rows: list[dict], reference: str = "rld", seed: int = 0) -> list[dict]:
    """The reference controller against every other one ON THE SAME PILES (the grid gives every
    controller the same seeds, slopes and materials): per (other, material, slope or "all") the
    piles on which BOTH attempts succeeded, and over them the mean of (reference - other) for mass,
    time and drift, with a percentile-bootstrap 95 % interval (10,000 resamples of the pairs).

    The paper's table compares means over each controller's own successful attempts; where one
    controller succeeds on few piles (the Tampier heuristic here), those means are over different
    piles. A difference over the same piles, with its interval, is the figure that says whether two
    controllers load the same mass. `both_successful` counts the pairs; with fewer than 2 the interval
    is NaN. Also per cell: the mean mass difference over ALL pairs (failed attempts count with the
    load they ended with)."""
    rs = [r for r in rows if r["table"] == "controllers"]
    by = {(r["controller"], r["material"], r["slope_deg"], r["seed"]): r for r in rs}
    rng = np.random.default_rng(seed)
    out = []
    others = [c for c in CONTROLLERS if c != reference and any(r["controller"] == c for r in rs)]
    if not any(r["controller"] == reference for r in rs):
        return out
    for c in others:
        for m in MATERIALS:
            slopes = sorted({r["slope_deg"] for r in rs if r["controller"] == c and r["material"] == m})
            for a in [*slopes, None] if slopes else []:
                pairs = [(by[k], o) for (cc, mm, aa, sd), o in by.items()
                         if cc == c and mm == m and (a is None or aa == a)
                         for k in [(reference, m, aa, sd)] if k in by]
                if not pairs:
                    continue
                ok = [(r, o) for r, o in pairs if r["success"] and o["success"]]
                row = {"reference": reference, "other": c, "material": m, "slope_deg": "all" if a is None else a,
                       "pairs": len(pairs), "both_successful": len(ok),
                       "mass_diff_all_kg": float(np.mean([r["loaded_kg"] - o["loaded_kg"] for r, o in pairs]))}
                for k in PAIRED_METRICS:
                    d = np.array([r[k] - o[k] for r, o in ok], dtype=float)
                    row[f"{k}_ref"] = float(np.mean([r[k] for r, _ in ok])) if ok else math.nan
                    row[f"{k}_other"] = float(np.mean([o[k] for _, o in ok])) if ok else math.nan
                    row[f"{k}_diff"] = float(d.mean()) if len(d) else math.nan
                    row[f"{k}_diff_lo"], row[f"{k}_diff_hi"] = _bootstrap_mean_ci(d, rng)
                out.append(row)
    return out


def markdown_paired(paired: list[dict]) -> str:
    """One row per (other controller, material) over all slopes, then the per-slope rows."""
    if not paired:
        return ""
    ref = paired[0]["reference"]
    R = ref.upper() if ref.startswith("rl") else ref
    L = [f"| {R} against | material | slope | piles (both successful) | mass {R} / other [kg] | "
         f"{R} - other: mass [kg] | time [s] | front drift [pp] | rear drift [pp] | mass, all piles [kg] |",
         "|---|---|---|---|---|---|---|---|---|---|"]

    def ci(r, k):
        if not math.isfinite(r[k + "_diff"]):
            return "-"
        lo, hi = r[k + "_diff_lo"], r[k + "_diff_hi"]
        band = f" [{lo:+.1f}, {hi:+.1f}]" if math.isfinite(lo) else ""
        return f"{r[k + '_diff']:+.1f}{band}"

    for r in sorted(paired, key=lambda r: (r["other"], r["material"], r["slope_deg"] != "all",
                                          0 if r["slope_deg"] == "all" else r["slope_deg"])):
        o = r["other"].upper() if r["other"].startswith("rl") else r["other"]
        a = "all" if r["slope_deg"] == "all" else f"{r['slope_deg']:g}"
        L.append(f"| {o} | {r['material']} | {a} | {r['pairs']} ({r['both_successful']}) | "
                 f"{_f(r['loaded_kg_ref'])} / {_f(r['loaded_kg_other'])} | {ci(r, 'loaded_kg')} | {ci(r, 'elapsed_s')} | "
                 f"{ci(r, 'front_drift_pct')} | {ci(r, 'rear_drift_pct')} | {r['mass_diff_all_kg']:+.1f} |")
    L += ["", f"Differences are {R} minus the other controller on the same piles where both succeeded, mean and "
              "percentile-bootstrap 95 % interval over the pairs; the last column is over every pair, failures "
              "included (with the load they ended with)."]
    return "\n".join(L) + "\n"


def _f(v, fmt="{:.1f}"):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else fmt.format(v)


def markdown_controllers(summary: list[dict]) -> str:
    """Laid out like the paper's table: a row per (metric, slope), a column per controller, one
    table per material."""
    L = []
    for m in MATERIALS:
        rows = [r for r in summary if r["material"] == m]
        if not rows:
            continue
        ctls = [c for c in CONTROLLERS if any(r["controller"] == c for r in rows)]
        slopes = [s for s in dict.fromkeys(r["slope_deg"] for r in rows)]
        L += [f"### {m} piles (successful attempts; success rate over all)", "",
              "| metric | slope | " + " | ".join(c.upper() if c.startswith("rl") else c for c in ctls) + " |",
              "|---|---|" + "---|" * len(ctls)]
        for label, k, pct in (("Success rate [%]", "success_rate", True), ("Loaded mass [kg]", "loaded_kg", False),
                              ("Elapsed time [s]", "elapsed_s", False), ("Front drift [%]", "front_drift_pct", False),
                              ("Rear drift [%]", "rear_drift_pct", False)):
            for a in slopes:
                cells = []
                for c in ctls:
                    r = next(r for r in rows if r["controller"] == c and r["slope_deg"] == a)
                    cells.append(_f(100 * r[k], "{:.0f}") if pct else f"{_f(r[k])} ± {_f(r[k + '_sd'])}")
                name = "all" if a == "all" else f"{a:g}"
                L.append(f"| {label} | {name} | " + " | ".join(cells) + " |")
        refused = {c: r["refused"] for r in rows if r["slope_deg"] == "all" and (c := r["controller"]) and r.get("refused")}
        if refused:
            L += ["", "Refused, counted as failures: " + ", ".join(f"{c.upper()} {n}" for c, n in refused.items())
                  + " attempts whose told slope (the LiDAR's, of a rough face's slice) lay outside the actor's trained "
                  "range: the policy node refuses it and the supervisor does not arm, so they did not run."]
        L.append("")
    return "\n".join(L)


def markdown_slope_error(summary: list[dict], told_range: tuple[float, float] | None = None) -> str:
    """The slope-error table; with `told_range` (the parameter file's pile range, over which the
    actors were trained), a told slope outside it is marked: the nodes refuse such an estimate (the
    machine would not move), so that cell is what the actor alone would do, not what the machine does."""
    if not summary:
        return ""
    out_of = (lambda r: told_range is not None and r["controller"] in ("rld", "rlc")    # noqa: E731
              and not (told_range[0] - 1e-9 <= r["told_deg"] <= told_range[1] + 1e-9))
    L = ["| controller | pile [deg] | told [deg] | error [deg] | success [%] | loaded mass [kg] | vs no error [%] |",
         "|---|---|---|---|---|---|---|"]
    for r in summary:
        L.append(f"| {r['controller'].upper()} | {r['slope_deg']:g} | {r['told_deg']:g}{' *' if out_of(r) else ''} | "
                 f"{r['error_deg']:+g} | {100 * r['success_rate']:.0f} | {_f(r['loaded_kg'])} ± {_f(r['loaded_kg_sd'])} | "
                 f"{_f(r['mass_change_pct'], '{:+.0f}')} |")
    if any(out_of(r) for r in summary):
        L += ["", f"\\* told a slope outside the pile range the actors were trained on ({told_range[0]:g}-"
                  f"{told_range[1]:g} deg): the policy node refuses such an estimate and commands zero, so on the "
                  "machine these attempts would not start; the row is what the actor alone does with it."]
    return "\n".join(L) + "\n"


def _write_csv(path: Path, rows: list[dict]) -> None:
    if not rows:
        path.write_text("")
        return
    keys = [k for k in rows[0] if k not in ("path", "profile")]
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def figures(rows: list[dict], err_summary: list[dict], out: Path) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    written = []
    rs = [r for r in rows if r["table"] == "controllers"]
    ctls = [c for c in CONTROLLERS if any(r["controller"] == c for r in rs)]
    if rs:   # loaded mass vs time, per controller (the paper's scatter)
        fig, axes = plt.subplots(1, len(ctls), figsize=(4 * len(ctls), 3.6), sharey=True, squeeze=False)
        for ax, c in zip(axes[0], ctls):
            for ok, mk, lab in ((True, "o", "success"), (False, "x", "failure")):
                pts = [(r["elapsed_s"], r["loaded_kg"]) for r in rs if r["controller"] == c and r["success"] == ok]
                if pts:
                    ax.scatter(*zip(*pts), marker=mk, s=18, label=lab)
            ax.set_title(c.upper() if c.startswith("rl") else c)
            ax.set_xlabel("time [s]")
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("loaded mass [kg]")
        axes[0][0].legend()
        fig.tight_layout()
        fig.savefig(out / "mass_vs_time.png", dpi=110)
        plt.close(fig)
        written.append("mass_vs_time.png")
    traced = [r for r in rs if "path" in r]
    if traced:   # bucket-tip paths in the XZ plane over the pile profile
        fig, axes = plt.subplots(1, len(ctls), figsize=(4 * len(ctls), 3.4), sharey=True, squeeze=False)
        xs = [x for r in traced for x, _ in r["path"]]
        for ax, c in zip(axes[0], ctls):
            for r in [r for r in traced if r["controller"] == c]:
                prof = np.array(r["profile"])
                ax.plot(prof[:, 0], prof[:, 1], color="0.6", lw=1)
                p = np.array(r["path"])
                ax.plot(p[:, 0], p[:, 1], lw=1.2)
            ax.set_title(f"{c.upper() if c.startswith('rl') else c}: 20 deg")
            ax.set_xlabel("x [m] (pile toe at 0)")
            ax.set_xlim(min(-0.2, min(xs) - 0.05), max(xs) + 0.3)
            ax.set_ylim(-0.05, 0.75)
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("z [m]")
        fig.tight_layout()
        fig.savefig(out / "tip_trajectories.png", dpi=110)
        plt.close(fig)
        written.append("tip_trajectories.png")
    if err_summary:   # success and mass vs slope error
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.6))
        for c in dict.fromkeys(r["controller"] for r in err_summary):
            for a in dict.fromkeys(r["slope_deg"] for r in err_summary):
                pts = [r for r in err_summary if r["controller"] == c and r["slope_deg"] == a]
                e = [r["error_deg"] for r in pts]
                a1.plot(e, [100 * r["success_rate"] for r in pts], marker="o", label=f"{c.upper()} {a:g} deg")
                a2.plot(e, [r["loaded_kg"] for r in pts], marker="o", label=f"{c.upper()} {a:g} deg")
        a1.set_xlabel("slope error (told - true) [deg]")
        a1.set_ylabel("success [%]")
        a2.set_xlabel("slope error (told - true) [deg]")
        a2.set_ylabel("loaded mass [kg]")
        for ax in (a1, a2):
            ax.grid(alpha=0.3)
        a1.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out / "slope_error.png", dpi=110)
        plt.close(fig)
        written.append("slope_error.png")
    return written


# what paper() writes into its --out: a previous run's are removed first, so that none of them (a paired table, a
# figure this run does not draw) is left beside the new ones (a review, 2026-11-30)
OUTPUT_FILES = ("attempts.csv", "table_controllers.csv", "table_controllers.md", "table_slope_error.csv",
                "table_slope_error.md", "table_paired.csv", "table_paired.md", "summary.json", "mass_vs_time.png",
                "tip_trajectories.png", "slope_error.png")


def paper(out: str | os.PathLike, episodes: int = 10, controllers=CONTROLLERS, slopes=SLOPES, materials=MATERIALS,
          errors=ERRORS, jobs_n: int = 0, seed: int = 3_000_000, config=None, policy_dirs: dict | None = None,
          progress=sys.stderr, stress: str | None = None, zones: str = "pile", zones_density: float | None = None) -> dict:
    out = Path(out)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)      # first: a folder that cannot be made is said before the run
    t0 = time.monotonic()
    try:
        jobs = grid(controllers, slopes, materials, errors, ERROR_PILES, episodes, seed, stress)
        rows = run(jobs, jobs_n, config, policy_dirs, progress, zones, zones_density)
    except BaseException:
        if created and not any(out.iterdir()):
            out.rmdir()          # a refused or interrupted run leaves no empty folder behind
        raise
    old = [f for f in OUTPUT_FILES if (out / f).is_file()]
    if old:                      # only now, the run done: a refused or interrupted one keeps the previous files
        for f in old:
            (out / f).unlink()
        if progress is not None:
            progress.write(f"lhd experiment paper: removed the previous run's {', '.join(old)} from {out}\n")
            progress.flush()
    ctl = summarize_controllers(rows)
    err = summarize_slope_error(rows)
    _write_csv(out / "attempts.csv", rows)
    _write_csv(out / "table_controllers.csv", ctl)
    _write_csv(out / "table_slope_error.csv", err)
    from lhd_loading_ros.task.config import load_config

    ep = (config if isinstance(config, dict) else load_config(config))["paper"]["episode"]
    md_c = markdown_controllers(ctl)
    md_e = markdown_slope_error(err, (float(ep["alpha_min_deg"]), float(ep["alpha_max_deg"])))
    paired = paired_comparison(rows)
    md_p = markdown_paired(paired)
    (out / "table_controllers.md").write_text(md_c)
    (out / "table_slope_error.md").write_text(md_e)
    if paired:
        _write_csv(out / "table_paired.csv", paired)
        (out / "table_paired.md").write_text(md_p)
    figs = figures(rows, err, out)
    summary = {"attempts": len(rows), "episodes_per_cell": episodes, "controllers": list(controllers),
               "slopes_deg": list(slopes), "materials": list(materials), "errors_deg": list(errors),
               "time_limit_s": TIME_LIMIT_S, "seed": seed, "stress": stress, "zones": zones, "zones_density": zones_density,
               "wall_s": time.monotonic() - t0,
               "jobs": jobs_n or usable_cores(), "figures": figs, "controllers_table": ctl, "slope_error_table": err,
               "paired_table": paired}
    (out / "summary.json").write_text(json_out.dumps(summary, indent=1))
    head = "" if stress is None else (f"Every attempt under the stress case `{stress}` (physical conditions on every "
                                      f"controller, sensor noise on the RL actors only).\n\n")
    if zones != "pile":
        rho = "the nominal bulk density" if zones_density is None else f"a bulk density of {zones_density:g} kg/m^3"
        head += (f"The zones are the end-zone node's: a wedge at the told slope and {rho}, blind to "
                 "each pile's own density and rocks, as on the machine.\n\n")
    summary["markdown"] = (head + md_c + ("\n### RLD against the other controllers on the same piles\n\n" + md_p if md_p else "")
                           + ("\n### Slope error (homogeneous piles, all attempts)\n\n" + md_e if md_e else ""))
    return summary
