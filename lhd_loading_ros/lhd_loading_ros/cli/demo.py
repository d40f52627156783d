"""`lhd demo --scripted`: the scripted maneuver on the in-process simulator (no ROS) instead of the
nodes. The flags of `lhd demo` that apply to it are honoured as the nodes' demo reads them
(`--episodes N`: N attempts in all, attempt i on slope i mod len(slopes); `--slope`/`--slopes`,
`--material`, `--seed`, `--config`, `--json`); the flags that only concern the nodes are refused by
name, never ignored."""
from __future__ import annotations

import sys

from lhd_loading_ros.task import json_out

# lhd demo's flags that only concern the nodes: refused with --scripted
NODE_ONLY_FLAGS = (("--policy", "policy"), ("--controller", "controller"), ("--mode", "mode"), ("--namespace", "namespace"),
                   ("--use-sim-time", "use_sim_time"), ("--log-dir", "log_dir"), ("--verbose", "verbose"))
SCRIPTED_MATERIALS = ("homogeneous", "nonhomogeneous")


def scripted_problem(args) -> str:
    """Why these parsed `lhd demo` arguments cannot run with --scripted ("" if they can)."""
    given = [flag for flag, attr in NODE_ONLY_FLAGS if getattr(args, attr, None)]
    if given:
        return (f"--scripted runs the scripted maneuver without the nodes; {', '.join(given)} "
                f"appl{'ies' if len(given) == 1 else 'y'} to the nodes only")
    if args.material not in SCRIPTED_MATERIALS:
        return (f"--scripted with --material {args.material}: the scripted demo loads one material, "
                f"expected {' or '.join(SCRIPTED_MATERIALS)}")
    if args.episodes < 1:
        return (f"--scripted with --episodes {args.episodes}: expected N >= 1 attempts in all (it does not run "
                "until Ctrl-C)")
    return ""


def scripted_plan(slopes, episodes: int) -> list[tuple[float, int]]:
    """Attempts per slope when `episodes` attempts cycle through `slopes` as the nodes' demo runs
    them (attempt i on slopes[i mod len(slopes)]): [(slope, attempts)] in the order given, a
    repeated slope counted once, slopes without an attempt left out."""
    counts: dict[float, int] = {}
    for i in range(episodes):
        s = float(slopes[i % len(slopes)])
        counts[s] = counts.get(s, 0) + 1
    return list(counts.items())


def scripted_demo(args, prog: str = "lhd demo") -> int:
    """Run the scripted maneuver for parsed `lhd demo --scripted` arguments: exit 2 with one line
    naming the flag when the arguments do not apply, else the table (or `--json`: one object, the
    per-slope rows) and exit 0."""
    why = scripted_problem(args)
    slopes = args.slopes or ([args.slope] if args.slope is not None else [15, 20, 25, 30])
    if not why:
        from lhd_loading_ros.cli.launcher import slope_range_problem
        from lhd_loading_ros.task.config import ConfigError, config_name, load_config

        try:
            cfg = load_config(args.config)
        except ConfigError as exc:
            print(f"{prog}: {exc}", file=sys.stderr)
            return 1
        why = slope_range_problem(slopes, cfg, "--slopes" if args.slopes else "--slope", config_name(args.config))
    if why:
        print(f"{prog}: {why}", file=sys.stderr)
        return 2
    from lhd_sim_node.demo import format_table, run_scripted

    plan = scripted_plan(slopes, args.episodes)
    rows: dict = {}
    for slope, n in plan:     # run_scripted's seeds: seed + 1000 * attempt + slope, as the default demo
        rows.update(run_scripted([int(slope) if slope.is_integer() else slope], n, args.material, args.seed,
                                 args.config))
    if args.json:
        print(json_out.dumps(rows))
        return 0
    per = {n for _, n in plan}
    split = f"{per.pop()} per slope" if len(per) == 1 else ", ".join(f"{n} on {s:g} deg" for s, n in plan)
    print(format_table(rows, f"Scripted maneuver (drive in; past x_midgoal or on wheel drift curl, then lift and "
                             f"curl), {args.material} material, {args.episodes} attempts ({split})"))
    return 0
