"""Scripted loading on the simulator, with a table laid out like the paper's results table
(success rate, material loaded, elapsed time, front and rear drift per slope)."""
from __future__ import annotations

import argparse
import json
import math

import numpy as np

from lhd_loading_ros.task.metrics import aggregate

from .env import LhdLoadingEnv
from .scripted import run_episode, scripted_action


def run_scripted(slopes=(15, 20, 25, 30), episodes: int = 3, material: str = "homogeneous", seed: int = 0,
                 config=None) -> dict:
    env = LhdLoadingEnv(variant="rld", config=config)
    res = []
    for slope in slopes:
        for e in range(episodes):
            res.append(run_episode(env, lambda s: scripted_action(s, env.p.x_midgoal, lift_on_drift=True),
                                   seed=seed + 1000 * e + int(slope),
                                   options={"slope_deg": float(slope), "material": material}))
    return table_rows(res, slopes, {"bucket_capacity": env.p.bucket_capacity})


def table_rows(results, slopes, meta: dict | None = None) -> dict:
    """Per slope: aggregate metrics, plus material, time and drift over the successful attempts
    (mean, sd), as the paper's results table reports them."""
    cap = (meta or {}).get("bucket_capacity", 30.0)
    rows = {}
    for slope in slopes:
        res = [r for r in results if abs(r.alpha_deg - float(slope)) < 0.5]
        if not res:
            continue
        ok = [r for r in res if r.success]
        row = aggregate(res, cap)
        row["successful"] = len(ok)
        for key, attr in (("loaded_ok", "loaded"), ("elapsed_ok", "elapsed_s"), ("front_ok", "front_drift_pct"),
                          ("rear_ok", "rear_drift_pct")):
            vals = [getattr(r, attr) for r in ok]
            row[key] = (float(np.mean(vals)), float(np.std(vals))) if vals else (math.nan, math.nan)
        rows[f"{float(slope):g}"] = row
    return rows


def format_table(rows: dict, title: str) -> str:
    def pm(v):
        return "     -      " if math.isnan(v[0]) else f"{v[0]:6.2f}±{v[1]:5.2f}"
    lines = [title, f"{'slope [deg]':>12} {'success':>8} {'loaded [kg]':>13} {'time [s]':>13} {'front drift %':>14} {'rear drift %':>14}  ASL"]
    for slope, r in rows.items():
        lines.append(f"{slope:>12} {r['success_rate']:8.2f} {pm(r['loaded_ok']):>13} {pm(r['elapsed_ok']):>13} "
                     f"{pm(r['front_ok']):>14} {pm(r['rear_ok']):>14}  {r['asl']:.2f}")
    lines.append("(material, time and drift over successful attempts, as in the paper's table)")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd demo", description=__doc__)
    ap.add_argument("--slopes", type=float, nargs="+", default=[15, 20, 25, 30])
    ap.add_argument("--episodes", type=int, default=3, help="attempts per slope")
    ap.add_argument("--material", choices=["homogeneous", "nonhomogeneous"], default="homogeneous")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = ap.parse_args(argv)
    rows = run_scripted([s if not float(s).is_integer() else int(s) for s in args.slopes], args.episodes,
                        args.material, args.seed)
    if args.json:
        print(json.dumps(rows))
    else:
        print(format_table(rows, f"Scripted maneuver (drive in; past x_midgoal or on wheel drift curl, then lift and curl), "
                                 f"{args.material} material, {args.episodes} attempts per slope"))
    return 0
