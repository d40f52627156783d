"""Aggregate several training runs: final figures across seeds (mean +- sd, interquartile
mean with a bootstrap 95 % interval) and the training curves of AR, AML and ASL with their
spread across seeds (like the paper's performance-evolution figures)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

METRICS = ("ar", "aml", "aff", "asl", "success_rate", "elapsed_s", "front_drift_pct", "rear_drift_pct")


def read_evals(run_dir) -> dict[str, np.ndarray]:
    path = Path(run_dir) / "evals.csv"
    if not path.is_file():
        raise FileNotFoundError(f"{run_dir} is not a training run: no evals.csv (expected the --out of lhd train)")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path} has no evaluations yet")
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0] if r_is_number(rows[0][k])}


def r_is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def iqm(x) -> float:
    """Interquartile mean: the mean of the middle 50 % (floor(n/4) values dropped at each end); NaN when
    any value is NaN (np.sort puts NaNs last, where they were dropped unseen: a review, 2026-11-30)."""
    x = np.sort(np.asarray(x, dtype=float))
    if np.isnan(x).any():
        return float("nan")
    k = len(x) // 4
    return float(np.mean(x[k: len(x) - k]))


def bootstrap_ci(x, stat=iqm, n: int = 10_000, level: float = 0.95, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of stat over runs (resampling runs with replacement)."""
    x = np.asarray(x, dtype=float)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(x), size=(n, len(x)))
    vals = np.array([stat(x[i]) for i in idx])
    lo, hi = np.quantile(vals, [(1 - level) / 2, 1 - (1 - level) / 2])
    return float(lo), float(hi)


def group_labels(paths: list) -> list[str]:
    """Labels of lhd report's groups, one per path given: its folder name, with as many parent folders as
    make it unique where two share a name (study1/rld, study2/rld: a review, 2026-11-30, found one group
    dropped when they were keyed by name), the same path given twice numbered."""
    parts = [Path(p).resolve().parts for p in paths]
    depth = [1] * len(paths)

    def label(i):
        return "/".join(parts[i][-depth[i]:])

    while True:
        seen: dict = {}
        for i in range(len(paths)):
            seen.setdefault(label(i), []).append(i)
        grow = [i for ids in seen.values() if len(ids) > 1 for i in ids if depth[i] < len(parts[i])]
        if not grow:
            break
        for i in grow:
            depth[i] += 1
    out, count = [], {}
    for i in range(len(paths)):
        lab = label(i)
        count[lab] = count.get(lab, 0) + 1
        out.append(lab if count[lab] == 1 else f"{lab} ({count[lab]})")
    return out


def summarize(run_dirs: list) -> dict:
    """Final evaluation of each run -> per metric: mean, sd, iqm, iqm_ci95, values."""
    finals = [read_evals(d) for d in run_dirs]
    steps = [int(f["step"][-1]) for f in finals]
    out = {"runs": [str(d) for d in run_dirs], "final_steps": steps, "planned_steps": [planned_steps(d) for d in run_dirs],
           "metrics": {}}
    for m in METRICS:
        vals = np.array([f[m][-1] for f in finals if m in f])
        if len(vals) == 0:
            continue
        out["metrics"][m] = {"mean": float(vals.mean()), "sd": float(vals.std(ddof=1)) if len(vals) > 1 else 0.0,
                             "iqm": iqm(vals), "iqm_ci95": list(bootstrap_ci(vals)), "values": vals.tolist()}
    return out


HELD_OUT_METRICS = ("success_rate", "asl", "aml", "elapsed_s", "front_drift_pct", "rear_drift_pct", "max_tilt_deg",
                    "tilt_over_5deg_rate", "refused_rate", "success_rate_run")
# refused_rate: the episodes told a slope outside the trained range, not run (the policy node refuses them); they
# count in success_rate as loading nothing, success_rate_run is over the run ones (task.metrics.aggregate)


def _stats(vals) -> dict:
    vals = np.asarray(vals, dtype=float)
    return {"mean": float(vals.mean()), "sd": float(vals.std(ddof=1)) if len(vals) > 1 else 0.0,
            "iqm": iqm(vals), "iqm_ci95": list(bootstrap_ci(vals)), "values": vals.tolist()}


def _held_out_one(job: tuple) -> dict:
    """One (run, condition) evaluation of held_out, in a worker process: the same call as in-process."""
    from lhd_loading_ros.learning.evaluate import evaluate_under
    from lhd_loading_ros.policy.actor_file import load_policy
    from lhd_loading_ros.task.config import load_config

    run_dir, condition, episodes, seed, config, zones, zones_density = job
    cfg = load_config(config)
    pol = load_policy(Path(run_dir) / "final").check_config(cfg)      # --config: the scaling it was trained with
    ev = evaluate_under(condition, pol.variant, pol.actor, cfg, episodes, seed, breakdown=True, zones=zones,
                        zones_density=zones_density)
    out = {m: ev[m] for m in HELD_OUT_METRICS}
    out["by_slope"] = {k: v["success_rate"] for k, v in ev["by_slope"].items()}
    out["zones_from"] = ev["zones_from"]
    return out


def held_out(run_dirs: list, conditions=("nominal",), episodes: int = 120, config=None, seed: int = 2_000_000,
             log=None, jobs: int = 1, zones: str = "pile", zones_density: float | None = None) -> dict:
    """Each run's final actor (`final/`, the end of training: no checkpoint or seed picking) on the
    held-out evaluation piles (`seed`, stratified as `lhd eval`), under each condition: "nominal",
    "randomized" (the config's domain randomisation drawn per episode) or a stress case of
    task.randomization.stress_conditions. RLC runs with the deployment filter, as on the machine; the
    zones are `zones`' (learning/evaluate.ZONES: the pile's own, or the end-zone node's, at its default
    density or `zones_density`).
    Returns {condition: {metric: mean, sd, iqm, iqm_ci95, values}}, the success per pile slope
    ("success_by_slope": {condition: {slope: the same statistics}}) and the runs."""
    from lhd_loading_ros.learning.evaluate import CONDITIONS, zones_fallback_warning, zones_nominal_density
    from lhd_loading_ros.task.config import load_config
    from lhd_loading_ros.task.randomization import STRESS_CASES

    for c in conditions:
        if c not in CONDITIONS + STRESS_CASES:
            raise ValueError(f"unknown condition {c!r}; expected nominal, randomized or one of {', '.join(STRESS_CASES)}")
    cfg = load_config(config)      # a bad parameter file fails here, before any worker starts
    zones_nominal_density(zones, zones_density)       # likewise wrong zones
    if zones == "end-zone-node":   # the end-zone node's density in use, for the warnings: set, or the config's
        from lhd_loading_ros.task.end_zone import nominal_density

        used_density = nominal_density(cfg) if zones_density is None else zones_density
    else:
        used_density = None
    runs = [Path(d) for d in run_dirs]
    missing = [str(d) for d in runs if not (d / "final" / "policy.json").is_file()]
    if missing:
        raise FileNotFoundError(f"no final actor (final/policy.json) in {', '.join(missing)}: training not finished")
    per = {c: {m: [] for m in HELD_OUT_METRICS} for c in conditions}
    by_slope: dict = {c: {} for c in conditions}      # success per pile slope: where the seeds fail
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    work = [(str(d), c, episodes, seed, config, zones, zones_density) for d in runs for c in conditions]
    if jobs == 1:
        results = map(_held_out_one, work)
    else:                          # every evaluation is seeded: the same figures as in one process
        import multiprocessing as mp

        pool = mp.get_context("spawn").Pool(min(jobs, len(work)))
        results = pool.imap(_held_out_one, work)       # in order, as they finish in turn
    try:
        for (d, c, *_), ev in zip(work, results):
            for m in HELD_OUT_METRICS:
                per[c][m].append(ev[m])
            for k, v in ev["by_slope"].items():
                by_slope[c].setdefault(k, []).append(v)
            if log:
                log(f"{d}: {c}: success {ev['success_rate']:.3f}, ASL {ev['asl']:.2f}, AML {ev['aml']:.1f} kg")
                warning = zones_fallback_warning({"zones_from": ev["zones_from"], "zones_density": used_density})
                if warning is not None:
                    log(f"{d}: {c}: {warning}")
    finally:
        if jobs > 1:
            pool.terminate()
    return {"runs": [str(d) for d in runs], "episodes": episodes, "seed": seed, "zones": zones,
            "zones_density": zones_density,
            "conditions": {c: {m: _stats(v) for m, v in per[c].items()} for c in conditions},
            "success_by_slope": {c: {k: _stats(v) for k, v in sorted(by_slope[c].items(), key=lambda kv: float(kv[0]))}
                                 for c in conditions}}


def format_held_out(label: str, h: dict) -> str:
    zones = "" if h.get("zones", "pile") == "pile" else (
        ", the end-zone node's zones" + (f" at {h['zones_density']:g} kg/m^3" if h.get("zones_density") else ""))
    lines = [f"{label}: {len(h['runs'])} final actors, held-out seed {h['seed']:,}, {h['episodes']} episodes each{zones}"]
    for c, ms in h["conditions"].items():
        lines.append(f"  {c}:")
        for m, v in ms.items():
            vals = ", ".join(f"{x:.3g}" for x in v["values"])
            lines.append(f"    {m:>16}: {v['mean']:9.3f} +- {v['sd']:7.3f}   IQM {v['iqm']:9.3f} "
                         f"[{v['iqm_ci95'][0]:.3f}, {v['iqm_ci95'][1]:.3f}]   ({vals})")
        for k, v in h.get("success_by_slope", {}).get(c, {}).items():
            vals = ", ".join(f"{x:.2f}" for x in v["values"])
            lines.append(f"    {'success, ' + k + ' deg':>16}: {v['mean']:9.3f} +- {v['sd']:7.3f}   ({vals})")
    return "\n".join(lines)


def plot_curves(groups: dict[str, list], path) -> Path:
    """groups: label -> run dirs. One panel per metric (AR, AML, ASL): mean across seeds with a
    +-1 sd band, on the evaluation steps the runs share."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for label, dirs in groups.items():
        evs = [read_evals(d) for d in dirs]
        n = min(len(e["step"]) for e in evs)
        x = evs[0]["step"][:n] / 1000.0
        for ax, (m, title) in zip(axes, (("ar", "Average return"), ("aml", "Average material loaded [kg]"),
                                         ("asl", "Average success level"))):
            y = np.stack([e[m][:n] for e in evs])
            mu = y.mean(0)
            sd = y.std(0, ddof=1) if len(evs) > 1 else np.zeros_like(mu)    # the sample sd, as the tables
            ax.plot(x, mu, label=f"{label} ({len(evs)} seeds)", marker="o" if n < 3 else None)   # one point: a dot
            ax.fill_between(x, mu - sd, mu + sd, alpha=0.25)
            ax.set_title(title)
            ax.set_xlabel("training steps [x1000]")
            ax.grid(alpha=0.3)
    axes[0].legend()
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def planned_steps(run_dir) -> int | None:
    """The steps the run was started for (run.json's DDPG settings), None where the file does not say."""
    try:
        return int(json.loads((Path(run_dir) / "run.json").read_text())["ddpg"]["total_steps"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def unfinished_note(s: dict) -> str:
    """A line naming runs whose last evaluation is not at their planned end, or that ended at different steps:
    their figures mix training stages (a review, 2026-11-29: "final step 20,000" was printed over a run at
    60,000 and one stopped at 20,000). "" when every run reached the same planned end."""
    finals, planned = s["final_steps"], s.get("planned_steps") or [None] * len(s["final_steps"])
    short = [f"{Path(r).name} at {f:,} of {p:,}" for r, f, p in zip(s["runs"], finals, planned) if p and f < p]
    if not short and len(set(finals)) <= 1:
        return ""
    at = ", ".join(f"{Path(r).name} {f:,}" for r, f in zip(s["runs"], finals))
    return (f"  warning: the runs' last evaluations are at different steps ({at})"
            + (f"; unfinished: {', '.join(short)} (resume them with the same lhd train command)" if short else "")
            + ": these figures mix training stages")


def format_summary(label: str, s: dict) -> str:
    finals = s["final_steps"]
    at = f"final step {finals[0]:,}" if len(set(finals)) == 1 else f"last steps {min(finals):,}-{max(finals):,}"
    lines = [f"{label}: {len(s['runs'])} runs, {at}"]
    note = unfinished_note(s)
    if note:
        lines.append(note)
    for m, v in s["metrics"].items():
        lines.append(f"  {m:>16}: {v['mean']:9.3f} +- {v['sd']:7.3f}   IQM {v['iqm']:9.3f} "
                     f"[{v['iqm_ci95'][0]:.3f}, {v['iqm_ci95'][1]:.3f}]")
    return "\n".join(lines)
