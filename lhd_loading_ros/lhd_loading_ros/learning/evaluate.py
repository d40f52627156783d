"""Noise-free evaluation of a policy on the simulator: the paper's metrics overall and by
slope and material.

The evaluation set is stratified: episode i uses slope EVAL_SLOPES[i % 4] and material
EVAL_MATERIALS[(i // 4) % 2] with seed ``seed + i`` (the seed draws the rest: soil
parameters, rocks, d_attack, attack speed). 120 episodes give 15 per (slope, material)
cell, and the same seed gives the same 120 piles to every policy.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from lhd_loading_ros.task.metrics import EpisodeResult, aggregate
from lhd_loading_ros.task.randomization import STRESS_MATERIAL, stress_conditions
from lhd_loading_ros.task.zones import ESTIMATE_SLOPE_RANGE_DEG

EVAL_SLOPES = (15.0, 20.0, 25.0, 30.0)
EVAL_MATERIALS = ("homogeneous", "nonhomogeneous")


def episode_conditions(i: int, seed: int) -> tuple[int, dict]:
    return seed + i, {"slope_deg": EVAL_SLOPES[i % 4], "material": EVAL_MATERIALS[(i // 4) % 2]}


def run_policy_episode(env, policy: Callable[[np.ndarray], np.ndarray], seed: int, options: dict,
                       refuse: bool = False) -> EpisodeResult:
    """One episode of `policy`. refuse: an episode whose told slope the policy node would refuse (outside
    the trained range: env.slope_refusal) is not run and counts as refused (EpisodeResult.refused), as on
    the machine; without it the actor runs it with its slope observation clipped to the range."""
    obs, _ = env.reset(seed=seed, options=options)
    if refuse and getattr(env, "slope_refusal", ""):
        return env.refused_result()
    while True:
        a = np.clip(np.asarray(policy(obs), dtype=np.float64), -1.0, 1.0)
        obs, _, term, trunc, info = env.step(a)
        if term or trunc:
            return info["episode_result"]


def evaluate(env, policy: Callable[[np.ndarray], np.ndarray], episodes: int, seed: int,
             bucket_capacity: float, breakdown: bool = True, stress: str | None = None, refuse: bool = False) -> dict:
    """Run `episodes` stratified episodes; return the aggregate metrics (see metrics.aggregate),
    plus ``by_slope`` / ``by_material`` breakdowns when asked, and ``wall_s``. stress: a named
    case of task.randomization.stress_conditions applied to every episode. refuse: episodes told a
    slope outside the trained range are not run but counted as refused, as the machine's nodes do
    (lhd eval, lhd report --held-out, lhd ship); off for the training's periodic evaluation, whose
    figures (and the tilt ramp that reads them) stay as every shipped run was trained."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    t0 = time.perf_counter()
    results = []
    zones_from: dict[str, int] = {}
    for i in range(episodes):
        s, opts = episode_conditions(i, seed)
        if stress is not None:
            opts["conditions"] = stress_conditions(stress, i, env.cfg)
            opts["material"] = STRESS_MATERIAL.get(stress, opts["material"])
        results.append(run_policy_episode(env, policy, s, opts, refuse=refuse))
        where = getattr(env, "zones_from", None)       # set at reset: where this episode's zones came from
        if where is not None and not results[-1].refused:     # a refused episode is judged by no zones
            zones_from[where] = zones_from.get(where, 0) + 1
    out = aggregate(results, bucket_capacity)
    out["zones_from"] = zones_from
    if breakdown:
        out["by_slope"] = {f"{a:g}": aggregate(rs, bucket_capacity)
                           for a in EVAL_SLOPES if (rs := [r for r in results if round(r.alpha_deg) == a])}
        out["by_material"] = {m: aggregate(rs, bucket_capacity)
                              for m in EVAL_MATERIALS if (rs := [r for r in results if r.material == m])}
    out["failures"] = {
        "refused": sum(r.refused for r in results),
        "restricted_zone": sum(r.failed for r in results),
        "timeout": sum(r.truncated and not r.success for r in results),
        "end_zone_low_level": sum(r.reached_end_zone and not r.success for r in results),
    }
    out["wall_s"] = time.perf_counter() - t0
    return out


CONDITIONS = ("nominal", "randomized")   # and the stress cases of task.randomization
# Where an evaluated attempt's zones come from (`--zones` of lhd eval, lhd report --held-out, lhd experiment
# paper). "pile": the simulated pile's own (its density and rocks in them), moved by a slope-estimate error, as
# the sim node publishes them and as every figure before 2026-11-29 (ninth session) was measured; "end-zone-node":
# the end-zone node's wedge at the told slope and the config's nominal bulk density, blind to the pile's own
# density and rocks, as on the machine and in the twin (task/end_zone.zones_at_nominal_density).
ZONES = ("pile", "end-zone-node")


def zones_fallback_warning(res: dict) -> str | None:
    """A line for the console when some episodes were judged with the pile's own zones because the end-zone
    node would have published none for them (an estimate outside the LiDAR's range, or a wedge at the told
    slope and the node's density too light to hold m_max): on the machine those attempts would not start,
    so their figures are not the machine's. None when every episode had the zones asked for."""
    fell = sum(n for k, n in res.get("zones_from", {}).items() if k.startswith("pile, "))
    if not fell:
        return None
    total = sum(res["zones_from"].values())
    density = res.get("zones_density")
    light = f", or a wedge at the told slope lighter than m_max at {density:g} kg/m^3" if density is not None else ""
    return (f"warning: {fell} of {total} episodes were judged with the pile's own zones: the end-zone node publishes "
            f"none for their told slope (outside the LiDAR's {ESTIMATE_SLOPE_RANGE_DEG[0]:g}-"
            f"{ESTIMATE_SLOPE_RANGE_DEG[1]:g} deg{light}); on the machine those attempts would not start")


def zones_nominal_density(zones: str, zones_density: float | None = None) -> bool:
    """The environment's zones_nominal_density for a name of ZONES, checked with the end-zone node's density
    set by hand (`--zones-density`, only with "end-zone-node", in the node's range); ValueError saying which."""
    if zones not in ZONES:
        raise ValueError(f"zones {zones!r}: expected one of {', '.join(ZONES)}")
    if zones_density is not None:
        from lhd_loading_ros.task.end_zone import density_problem

        if zones != "end-zone-node":
            raise ValueError(f"--zones-density {zones_density:g} is the end-zone node's density: it needs --zones "
                             "end-zone-node")
        if density_problem(zones_density):
            raise ValueError(f"--zones-density {zones_density:g}: {density_problem(zones_density)}")
    return zones == "end-zone-node"


def evaluate_under(condition: str, variant: str, actor, cfg: dict, episodes: int, seed: int,
                   breakdown: bool = False, zones: str = "pile", zones_density: float | None = None) -> dict:
    """`evaluate` of an actor under a named condition, as the policy node runs it (RLC with the
    deployment filter): "nominal", "randomized" (the config's domain randomisation drawn per
    episode) or a stress case of task.randomization.stress_conditions, with the zones of `zones`
    (ZONES; zones_density: the end-zone node's `density`, None its default). Used by `lhd report --held-out`
    and `lhd ship`."""
    from lhd_sim_node.env import LhdLoadingEnv   # the simulator only where it runs

    from lhd_loading_ros.task.randomization import STRESS_CASES

    if condition not in CONDITIONS + STRESS_CASES:
        raise ValueError(f"unknown condition {condition!r}; expected nominal, randomized or one of "
                         f"{', '.join(STRESS_CASES)}")
    env = LhdLoadingEnv(variant, cfg, deploy_filter=(variant == "rlc"), randomize=(condition == "randomized"),
                        zones_from_estimate=True, zones_nominal_density=zones_nominal_density(zones),
                        zones_density=zones_density)
    return evaluate(env, actor, episodes, seed, cfg["task"]["bucket_capacity"], breakdown=breakdown,
                    stress=None if condition in CONDITIONS else condition, refuse=True)
