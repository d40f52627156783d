"""The `lhd` command line.

  lhd demo [--slopes ...] [--episodes N]   the main job (scripted loading on the simulator)
  lhd bench sim [--json] [--steps N]       simulator speed
  lhd bench bridge [--json]                serial parser throughput and frame-to-publish latency
  lhd bench perception [--json]            ArUco frames/s (one core) and slope-fit time
  lhd config check [PATH]                  validate a parameter file
  lhd mjcf [--out FILE]                    the MJCF of the scaled LHD, generated from the parameters
"""
from __future__ import annotations

import argparse
import json
import sys


def _bench(args) -> int:
    if args.what == "sim":
        from lhd_sim_node.bench import bench_sim

        res = bench_sim(steps=args.steps, seed=args.seed, config=args.config, rounds=args.rounds)
    elif args.what == "perception":
        from .perception.bench import bench_perception

        res = bench_perception()
    elif args.what == "bridge":
        from lhd_hw_bridge.bench import bench_bridge

        res = bench_bridge(seconds=args.seconds)
    else:
        print(f"lhd bench: unknown benchmark {args.what!r}; expected: sim, bridge, perception", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(res))
    else:
        for k, v in res.items():
            print(f"{k:>30}: {v}")
    return 0


def _config(args) -> int:
    from .config import ConfigError, default_config_path, load_config

    try:
        path = args.path or default_config_path()
        load_config(path)
    except ConfigError as exc:
        print(exc, file=sys.stderr)
        return 1
    print(f"{path}: ok")
    return 0


def _mjcf(args) -> int:
    from lhd_sim_node.mjcf import build_mjcf

    from .config import ConfigError, load_config

    try:
        xml = build_mjcf(load_config(args.config))
    except ConfigError as exc:
        print(exc, file=sys.stderr)
        return 1
    if args.out:
        with open(args.out, "w") as f:
            f.write(xml)
        print(f"wrote {args.out} (view it: python -m mujoco.viewer --mjcf={args.out})")
    else:
        print(xml)
    return 0


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(prog="lhd", description="LHD loading: simulator, training and ROS tools")
    sub = ap.add_subparsers(dest="cmd", required=True)
    p_demo = sub.add_parser("demo", help="the main job: load piles of 15-30 deg and print the results table",
                            add_help=False)
    p_demo.add_argument("rest", nargs=argparse.REMAINDER)
    p_bench = sub.add_parser("bench", help="benchmarks that print their figures")
    p_bench.add_argument("what", help="sim | bridge | perception")
    p_bench.add_argument("--seconds", type=float, default=4.0, help="bridge: latency measurement time")
    p_bench.add_argument("--json", action="store_true")
    p_bench.add_argument("--steps", type=int, default=3000)
    p_bench.add_argument("--seed", type=int, default=0)
    p_bench.add_argument("--rounds", type=int, default=3, help="alternating runs; the best of each is reported")
    p_bench.add_argument("--config", default=None, help="parameter file (default: config/lhd_params.yaml)")
    p_mjcf = sub.add_parser("mjcf", help="write the MJCF of the scaled LHD generated from the parameter file")
    p_mjcf.add_argument("--out", help="file to write (default: print)")
    p_mjcf.add_argument("--config", default=None)
    p_cfg = sub.add_parser("config", help="parameter file tools")
    p_cfg.add_argument("action", choices=["check"])
    p_cfg.add_argument("path", nargs="?")
    if argv[:1] == ["demo"]:
        from lhd_sim_node.demo import main as demo_main

        return demo_main(argv[1:])
    args = ap.parse_args(argv)
    if args.cmd == "bench":
        return _bench(args)
    if args.cmd == "config":
        return _config(args)
    if args.cmd == "mjcf":
        return _mjcf(args)
    ap.error(f"unknown command {args.cmd}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
