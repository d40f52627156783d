"""The `lhd` command line.

  lhd demo                                 the main job: sim node + policy node (shipped RLD actor) on 15-30 deg piles
  lhd up sim [--policy DIR | --controller tampier|teacher] [--slope DEG] [--episodes N] [--namespace NS] [--use-sim-time] [--log-dir DIR]
                                           sim node + policy node over DDS until done / Ctrl-C / SIGTERM
  lhd echo TOPIC [--count N]               print a topic's messages as YAML (QoS matched to the publishers)
  lhd bench sim [--json] [--steps N] [--ros]  simulator speed (--ros: through a sim node over DDS)
  lhd bench bridge [--json]                serial parser throughput and frame-to-publish latency
  lhd bench perception [--json]            ArUco frames/s (one core) and slope-fit time
  lhd train --variant rld|rlc --seed N     DDPG with the paper's protocol (resumable; --seeds 0-4 in parallel)
  lhd eval --policy DIR [--json]           the paper's metrics, overall and by slope and material
  lhd train ... --env ros --namespaces /sim0,/sim1   one learner from several lockstep sim nodes (lhd up sim --count N)
  lhd sweep STUDY.yaml [--address A]       a study on Ray (local or a cluster), resumable, run folders for lhd report
  lhd report RUNS... [--plot PNG]          final figures across seeds and the training curves
  lhd experiment paper [--episodes N] [--out DIR] [--jobs J]
                                           the paper's real-world tables in simulation: controllers x slopes x
                                           materials, and the slope-error table (markdown, CSV, figures)
  lhd ship --variant V RUNS_DIR            ship a variant's median seed (final actor) to policies/V with its model card
  lhd bench train [--json] [--vs-sb3] [--jobs N] [--config F] [--randomize]
                                           training-loop speed, the projected protocol and study times
  lhd bench node [--json]                  policy node latency and 10 Hz jitter against the sim node
  lhd config check [PATH]                  validate a parameter file
  lhd mjcf [--out FILE]                    the MJCF of the scaled LHD, generated from the parameters
  lhd validate physics [--plots DIR] [--json] [--quick]
                                           the simulator's physics next to independent references (issue 13)
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lhd_loading_ros.task import json_out
from lhd_loading_ros.cli.argtypes import nonneg_int, pos_int
from lhd_loading_ros.task.cores import usable_cores


def _bench(args) -> int:
    if args.what == "sim" and args.ros:
        from lhd_loading_ros.task.config import ConfigError
        from lhd_sim_node.bench_ros import bench_sim_ros

        try:
            res = bench_sim_ros(steps=args.steps if args.steps is not None else 1000, seed=args.seed,
                                config=args.config, rounds=args.rounds)
        except (ConfigError, ValueError, TimeoutError, RuntimeError) as exc:
            print(f"lhd bench sim --ros: {exc}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            print("\nlhd bench sim --ros: interrupted (the sim node was stopped)", file=sys.stderr)
            return 130
    elif args.what == "sim":
        from lhd_sim_node.bench import bench_sim

        res = bench_sim(steps=args.steps if args.steps is not None else 3000, seed=args.seed, config=args.config,
                        rounds=args.rounds)
    elif args.what == "perception":
        from lhd_loading_ros.cli.bench_perception import bench_perception

        res = bench_perception()
    elif args.what == "train":
        from lhd_loading_ros.cli.bench_train import bench_train

        steps = args.steps if args.steps is not None else 3000
        if args.vs_sb3 and args.jobs > 1:
            print("lhd bench train: --vs-sb3 times one process; leave --jobs out", file=sys.stderr)
            return 2
        if args.jobs < 1:
            print(f"lhd bench train: --jobs must be >= 1, got {args.jobs}", file=sys.stderr)
            return 2
        if args.jobs > usable_cores():
            print(f"lhd bench train: --jobs {args.jobs} is more than this machine's {usable_cores()} usable cores: the "
                  "processes share them, and the projection is of that oversubscribed study", file=sys.stderr)
        from lhd_loading_ros.task.config import ConfigError, load_config

        try:
            load_config(args.config)        # a bad parameter file is named here, not in a worker's traceback
        except (ConfigError, OSError, ValueError) as exc:
            print(f"lhd bench train: {exc}", file=sys.stderr)
            return 2
        if args.vs_sb3:
            res = bench_train(steps=steps, seed=args.seed, config=args.config, vs_sb3=True, randomize=args.randomize)
        else:
            from lhd_loading_ros.cli.bench_train import bench_train_jobs

            res = bench_train_jobs(args.jobs, steps=steps, seed=args.seed, config=args.config, randomize=args.randomize)
    elif args.what == "node":
        from lhd_loading_ros.cli.bench_node import bench_node

        res = bench_node(cycles=args.cycles)
    elif args.what == "bridge":
        from lhd_hw_bridge.bench import bench_bridge

        res = bench_bridge(seconds=args.seconds)
    else:
        print(f"lhd bench: unknown benchmark {args.what!r}; expected: sim, train, node, bridge, perception, twin", file=sys.stderr)
        return 2
    if args.json:
        print(json_out.dumps(res))
    else:
        for k, v in res.items():
            print(f"{k:>30}: {v}")
    return 0


TORCH_PIN, TORCH_INDEX = "2.13.0", "https://download.pytorch.org/whl/cpu"     # requirements.txt


def _train(args) -> int:
    from lhd_loading_ros.task.config import ConfigError
    from lhd_loading_ros.learning.runner import parse_seeds, run_seeds

    if args.seeds and args.seed is not None:
        print(f"lhd train: --seed {args.seed} and --seeds {args.seeds} are alternatives: one run, or several in "
              "parallel", file=sys.stderr)
        return 2
    try:
        seeds = parse_seeds(args.seeds) if args.seeds else [0 if args.seed is None else args.seed]
    except ValueError as exc:
        print(f"lhd train: {exc}", file=sys.stderr)
        return 2
    if args.steps is not None and args.steps < 1:
        print(f"lhd train: --steps must be >= 1, got {args.steps}", file=sys.stderr)
        return 2
    if args.jobs < 0:            # as lhd report / experiment: 0 is one per core (a review: -1 looped forever)
        print(f"lhd train: --jobs must be >= 0 (0: one per core), got {args.jobs}", file=sys.stderr)
        return 2
    namespaces = None
    if args.env == "ros":
        namespaces = [n.strip() for n in (args.namespaces or "").split(",") if n.strip()]
        if not namespaces:
            print("lhd train: --env ros needs --namespaces, the sim nodes' namespaces (e.g. /sim0,/sim1; start them "
                  "with `lhd up sim --count 2`)", file=sys.stderr)
            return 2
        if len(seeds) > 1:
            print("lhd train: --env ros trains one seed (its sim nodes serve one learner); give --seed, not --seeds",
                  file=sys.stderr)
            return 2
    elif args.namespaces:
        print("lhd train: --namespaces is for --env ros", file=sys.stderr)
        return 2
    try:
        # training needs it: said in one line, not an ImportError traceback (a review, 2026-11-30)
        __import__("torch")
    except ImportError as exc:
        print(f"lhd train: PyTorch is not importable ({exc}): training needs it; install the pinned CPU build with "
              f"`pip install torch=={TORCH_PIN} --index-url {TORCH_INDEX}` (requirements.txt)", file=sys.stderr)
        return 1
    out = Path(args.out) if args.out else Path("runs") / args.variant
    if len(seeds) > 1:
        extra = (["--steps", str(args.steps)] if args.steps else []) + (["--config", args.config] if args.config else [])
        extra += ["--no-resume"] if not args.resume else []
        extra += ["--randomize"] if args.randomize else []
        for k in args.keep_checkpoint:
            extra += ["--keep-checkpoint", str(k)]
        if args.branch_from and "{seed}" not in args.branch_from:
            print("lhd train: with --seeds, --branch-from names each seed's checkpoint with {seed}, e.g. "
                  "runs/x/seed_{seed}/checkpoint_step250000.pt", file=sys.stderr)
            return 2
        per_seed = (lambda s: ["--branch-from", args.branch_from.format(seed=s)]) if args.branch_from else None
        return run_seeds(args.variant, seeds, out, args.jobs or usable_cores(), extra, per_seed=per_seed)
    from lhd_loading_ros.learning.train import train

    run_dir = out if args.out and not args.seeds else out / f"seed_{seeds[0]}"
    try:
        ev = train(args.variant, seeds[0], run_dir, steps=args.steps, config=args.config, resume=args.resume,
                   progress=args.progress, randomize=args.randomize, env_kind=args.env, namespaces=namespaces,
                   ros_timeout=args.ros_timeout, keep_checkpoints=args.keep_checkpoint,
                   branch_from=args.branch_from.format(seed=seeds[0]) if args.branch_from else None)
    except (ConfigError, ValueError) as exc:
        print(f"lhd train: {exc}", file=sys.stderr)
        return 1
    except (TimeoutError, RuntimeError) as exc:      # a sim node missing, refusing or gone (--env ros)
        again = ("\nthe run resumes from its last checkpoint with the same command"
                 if (run_dir / "checkpoint.pt").exists() else "")
        print(f"lhd train: {exc}{again}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        if (run_dir / "checkpoint.pt").exists():
            print(f"\ninterrupted; run the same command again to resume from {run_dir}/checkpoint.pt", file=sys.stderr)
        else:       # before the first checkpoint (every training.checkpoint_every steps)
            print(f"\ninterrupted before the first checkpoint: nothing to resume from in {run_dir}; the same command "
                  "starts the run again", file=sys.stderr)
        return 130
    print(json_out.dumps({"run": str(run_dir), "final": ev}))
    return 0


def _eval(args) -> int:
    from lhd_sim_node.env import LhdLoadingEnv

    from lhd_loading_ros.task.config import ConfigError, load_config
    from lhd_loading_ros.learning.evaluate import evaluate, zones_fallback_warning, zones_nominal_density
    from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy

    if args.seed < 0:
        print(f"lhd eval: --seed must be >= 0, got {args.seed}", file=sys.stderr)
        return 2
    if args.controller == "tampier":
        from lhd_loading_ros.learning.baselines import run_cli

        if args.policy is not None:
            print(f"lhd eval: --policy {args.policy} with --controller tampier: the heuristic runs no actor (a review "
                  "found the folder ignored without a word); drop --policy, or drop --controller tampier to evaluate "
                  "the actor", file=sys.stderr)
            return 2
        if args.randomize or args.stress or args.deploy_filter or args.zones != "pile" or args.zones_density is not None:
            print("lhd eval: --randomize, --stress, --deploy-filter and --zones apply to --controller actor only "
                  "(lhd experiment paper --controllers tampier --zones end-zone-node runs the heuristic with the "
                  "end-zone node's zones)", file=sys.stderr)
            return 2
        return run_cli(args.episodes, args.seed, args.slopes or "15,20,25,30", args.material or "both",
                       10.0 if args.time_limit is None else args.time_limit, args.config, args.tampier_config,
                       args.json)
    tampier_only = [f for f, v in (("--slopes", args.slopes), ("--material", args.material),
                                   ("--time-limit", args.time_limit), ("--tampier-config", args.tampier_config))
                    if v is not None]
    if tampier_only:
        print(f"lhd eval: {', '.join(tampier_only)} appl{'ies' if len(tampier_only) == 1 else 'y'} to --controller "
              "tampier only; an actor is evaluated on "
              "the paper's stratified set (15-30 deg piles of both materials, the environment's 200 steps)",
              file=sys.stderr)
        return 2
    if args.randomize and args.stress:
        print("lhd eval: --randomize and --stress are alternatives: drawn conditions, or one named stress case "
              "in every episode", file=sys.stderr)
        return 2
    if args.episodes < 1:
        print(f"lhd eval: --episodes must be >= 1, got {args.episodes}", file=sys.stderr)
        return 2
    try:
        nominal = zones_nominal_density(args.zones, args.zones_density)
    except ValueError as exc:
        print(f"lhd eval: {exc}", file=sys.stderr)
        return 2
    if not args.policy:
        print("lhd eval: --policy DIR is required for --controller actor", file=sys.stderr)
        return 2
    try:
        pol = load_policy(args.policy)
        cfg = load_config(args.config)
        pol.check_config(cfg)
    except (PolicyFileError, ConfigError) as exc:
        print(f"lhd eval: {exc}", file=sys.stderr)
        return 1
    deploy = args.deploy_filter
    if deploy and pol.variant != "rlc":
        print(f"lhd eval: --deploy-filter is the RLC deployment filter; {args.policy} is an {pol.variant.upper()} actor, "
              "which has none: leave the flag out", file=sys.stderr)
        return 2
    env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=deploy, randomize=args.randomize or None,
                        zones_from_estimate=True, zones_nominal_density=nominal, zones_density=args.zones_density)
    res = evaluate(env, pol.actor, args.episodes, args.seed, cfg["task"]["bucket_capacity"], stress=args.stress,
                   refuse=not args.run_refused)
    res.update({"policy": str(args.policy), "variant": pol.variant, "seed": args.seed, "deploy_filter": deploy,
                "refuse": not args.run_refused,
                "randomize": env.randomize, "stress": args.stress, "zones": args.zones,
                "zones_density": env.rho_nominal if args.zones != "pile" else None})
    if args.json:
        print(json_out.dumps(res))
    else:
        print(format_eval(res))
    if (warning := zones_fallback_warning(res)) is not None:
        print(f"lhd eval: {warning}", file=sys.stderr)
    return 0


def format_eval(res: dict) -> str:
    # tilt: the mean of the attempts' largest pitch of the machine (rear lifting), and the share above 5 deg
    head = (f"{'':>16} {'episodes':>8} {'success':>8} {'ASL':>5} {'AML kg':>7} {'AFF':>5} {'AR':>8} {'time s':>6} "
            f"{'front %':>7} {'rear %':>6} {'tilt deg':>8} {'>5 deg':>6}")
    def row(name, r):
        return (f"{name:>16} {r['episodes']:>8} {r['success_rate']:>8.2f} {r['asl']:>5.2f} {r['aml']:>7.1f} "
                f"{r['aff']:>5.2f} {r['ar']:>8.1f} {r['elapsed_s']:>6.2f} {r['front_drift_pct']:>7.1f} {r['rear_drift_pct']:>6.1f} "
                f"{r.get('max_tilt_deg', float('nan')):>8.2f} {r.get('tilt_over_5deg_rate', float('nan')):>6.2f}")
    dr = ((", domain randomisation" if res.get("randomize") else "") + (f", stress {res['stress']}" if res.get("stress") else "")
          + (f", the end-zone node's zones at {res['zones_density']:g} kg/m^3" if res.get("zones", "pile") != "pile"
             else ""))
    lines = [f"policy {res['policy']} ({res['variant'].upper()}), evaluation seed {res['seed']}{dr}", head, row("all", res)]
    lines += [row(f"{k} deg", v) for k, v in res.get("by_slope", {}).items()]
    lines += [row(k, v) for k, v in res.get("by_material", {}).items()]
    f = res.get("failures", {})
    lines.append(f"failures: restricted zone {f.get('restricted_zone', 0)}, timeout {f.get('timeout', 0)}, "
                 f"end zone below SL 1 {f.get('end_zone_low_level', 0)}")
    if res.get("refused"):
        lines.append(f"refused: {res['refused']} of {res['episodes']} episodes told a slope outside the trained range "
                     f"were not run (the policy node refuses them; success counts them as loading nothing); "
                     f"success over the {res['episodes'] - res['refused']} run: {res['success_rate_run']:.2f}; "
                     "the loading figures (ASL ... tilt) are over the run ones")
    return "\n".join(lines)


def _floats(text: str, what: str) -> tuple:
    try:
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        print(f"lhd experiment paper: --{what} {text!r}: expected comma-separated numbers, e.g. 15,20,25,30",
              file=sys.stderr)
        raise SystemExit(2) from None


def _experiment(args) -> int:
    from lhd_loading_ros.learning import experiment as ex

    ctls = tuple(c.strip() for c in args.controllers.split(",") if c.strip())
    mats = tuple(m.strip() for m in args.materials.split(",") if m.strip())
    for m in mats:
        if m not in ex.MATERIALS:
            print(f"lhd experiment paper: --materials: unknown material {m!r}; expected {', '.join(ex.MATERIALS)}",
                  file=sys.stderr)
            return 2
    policy_dirs = {k: v for k, v in (("rld", args.rld), ("rlc", args.rlc)) if v}
    try:
        res = ex.paper(args.out, args.episodes, ctls, _floats(args.slopes, "slopes"), mats, _floats(args.errors, "errors"),
                       args.jobs, args.seed, args.config, policy_dirs, stress=args.stress, zones=args.zones,
                       zones_density=args.zones_density)
    except ValueError as exc:
        print(f"lhd experiment paper: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json_out.dumps({k: v for k, v in res.items() if k != "markdown"}))
    else:
        print(res["markdown"])
        print(f"{res['attempts']} attempts in {res['wall_s']:.0f} s on {res['jobs']} process{'es' if res['jobs'] != 1 else ''}; tables, CSV and "
              f"figures in {args.out}")
    return 0


def _sweep(args) -> int:
    from lhd_loading_ros.learning.sweep import StudyError, sweep

    if args.jobs is not None and args.jobs < 0:
        print(f"lhd sweep: --jobs must be >= 0 (0: one per core), got {args.jobs}", file=sys.stderr)
        return 2
    try:
        return sweep(args.study, address=args.address, jobs=args.jobs)
    except StudyError as exc:
        print(f"lhd sweep: {exc}", file=sys.stderr)
        return 2
    except ConnectionError as exc:
        print(f"lhd sweep: cannot reach the Ray cluster at {args.address}: {exc}", file=sys.stderr)
        return 1


def _report(args) -> int:
    from lhd_loading_ros.learning.report import format_summary, plot_curves, summarize

    if args.jobs < 0:
        print(f"lhd report: --jobs must be >= 0 (0: one per core), got {args.jobs}", file=sys.stderr)
        return 2
    if (args.zones != "pile" or args.zones_density is not None) and not args.held_out:
        print("lhd report: --zones and --zones-density apply to --held-out only: the training curves were measured "
              "by the training itself", file=sys.stderr)
        return 2
    from lhd_loading_ros.learning.report import group_labels

    found = []
    for r in args.runs:
        p = Path(r)
        dirs = sorted(d for d in p.glob("seed_*") if d.is_dir()) if not (p / "evals.csv").exists() else [p]
        if not dirs:
            print(f"lhd report: {r} holds no training run (no evals.csv, no seed_*/)", file=sys.stderr)
            return 2
        found.append((p, dirs))
    # a group by its folder's name, with its parents where two share one (study1/rld, study2/rld); one run by its path
    multi = [i for i, (p, dirs) in enumerate(found) if len(dirs) > 1]       # by position: a path given twice is two
    names = dict(zip(multi, group_labels([found[i][0] for i in multi])))
    groups: dict[str, list] = {}
    for i, (p, dirs) in enumerate(found):
        label = names[i] if len(dirs) > 1 else str(p)
        while label in groups:           # one run's path equal to a group's label, or a path given twice
            label += "'"
        groups[label] = dirs
    try:
        summaries = {k: summarize(v) for k, v in groups.items()}
        if args.held_out:
            from lhd_loading_ros.learning.report import held_out

            conds = tuple(c.strip() for c in args.held_out.split(",") if c.strip())
            for k, v in groups.items():
                summaries[k]["held_out"] = held_out(v, conds, args.episodes, args.config,
                                                    log=None if args.json else print,
                                                    jobs=args.jobs or usable_cores(), zones=args.zones,
                                                    zones_density=args.zones_density)
    except (FileNotFoundError, ValueError) as exc:
        print(f"lhd report: {exc}", file=sys.stderr)
        return 1
    if args.plot:
        plot_curves(groups, args.plot)
    if args.json:
        print(json_out.dumps(summaries))
    else:
        from lhd_loading_ros.learning.report import format_held_out

        for k, s in summaries.items():
            print(format_summary(k, s))
            if "held_out" in s:
                print(format_held_out(k, s["held_out"]))
        if args.plot:
            print(f"training curves: {args.plot}")
    return 0


def _config(args) -> int:
    from lhd_loading_ros.task.config import ConfigError, default_config_path, load_config

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

    from lhd_loading_ros.task.config import ConfigError, load_config

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


# commands whose second word is a subcommand (how a one-line error names the command)
GROUPS = ("up", "attempt", "validate", "bench", "experiment", "config", "bag", "estop")


def main(argv=None) -> int:
    """`lhd ...`; output cut off by its reader (`lhd attempts RUN | head`) ends quietly, not with a
    BrokenPipeError traceback (status 1, as the Python documentation's SIGPIPE note does)."""
    try:
        rc = _main(argv)
        sys.stdout.flush()
        return rc
    except BrokenPipeError:
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())   # the interpreter's own flush at exit must not raise again
        return 1
    except RuntimeError as exc:
        # the simulator could not set up an episode of this file (AttackError: the attack drive did not bury the
        # bucket; SimulationError: MuJoCo found the state unstable), e.g. a legal but extreme material: one line
        # naming it, as the sim node does (a review: a traceback from `lhd eval --controller tampier`)
        if type(exc).__name__ not in ("AttackError", "SimulationError"):
            raise
        args = sys.argv[1:] if argv is None else list(argv)
        words = args[:2] if args[:1] and args[0] in GROUPS and len(args) > 1 else args[:1]
        what = ("the attack drive could not bury the bucket in a pile of this parameter file"
                if type(exc).__name__ == "AttackError" else "MuJoCo found the simulation unstable")
        print(f"lhd {' '.join(words)}: {what}: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        # a file or folder the command cannot read or write (`--out /etc/passwd/x`, a folder that does
        # not exist): the path and the system's reason in one line, not a traceback (a review)
        words = [a for a in (sys.argv[1:] if argv is None else list(argv)) if not a.startswith("-") and "/" not in a][:2]
        print(f"lhd {' '.join(words)}: {exc}", file=sys.stderr)
        return 1


def _main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    from lhd_loading_ros.learning.evaluate import ZONES as EVAL_ZONES   # names only (numpy, no simulator)
    from lhd_loading_ros.task.randomization import STRESS_CASES

    ZONES_HELP = ("where the zones (d_end, the end zone and the restricted zone that end an attempt) come from: pile "
                  "(default): the simulated pile's own, with its density and rocks (what the sim node publishes), "
                  "moved by a slope-estimate error as the end-zone node would move them; end-zone-node: the end-zone "
                  "node's wedge at the told slope and the "
                  "config's nominal bulk density, blind to the pile's own density and rocks, as on the machine and in "
                  "the twin (docs/end_zone.md)")
    ZONES_DENSITY_HELP = ("with --zones end-zone-node: the end-zone node's `density` parameter (kg/m^3, 500-6,000; "
                          "default the config's nominal, 1,880 for gravel), as set on the machine for the material")

    ap = argparse.ArgumentParser(prog="lhd", description="LHD loading: simulator, training and ROS tools")
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name, hlp in (("demo", "the main job: sim + policy nodes load piles of 15-30 deg, results table"),
                      ("up", "up sim: the sim node and the policy node over DDS; up real --port DEV: the "
                             "real-machine stack (bridge, perception, end zone, supervisor, mux, teleop, "
                             "controller, recorder); up twin: that stack against the simulator as the Due, "
                             "with simulated camera and LiDAR"),
                      ("echo", "print a topic's messages as YAML"),
                      ("arm", "preflight, then arm an attempt (the supervisor's /lhd/arm)"),
                      ("abort", "end the attempt now (the supervisor's /lhd/abort)"),
                      ("attempt", "attempt mass KG [--attempt N]: record the weighed mass of an attempt"),
                      ("attempts", "attempts RUN_DIR: the paper's results table from a run's attempts.csv"),
                      ("replay", "replay BAG [--plot OUT.png]: an attempt's metrics and plots from its rosbag2"),
                      ("bag", "bag recover BAG [--out DIR]: a bag never closed (recorder killed, power lost) "
                              "rewritten as a complete one"),
                      ("estop", "estop on|off|status: the software emergency stop (/lhd/estop)"),
                      ("validate", "validate physics [--plots DIR] [--json] [--quick] [--config F]: the "
                                   "simulator's physics next to independent hand-calculation references")):
        sub.add_parser(name, help=hlp, add_help=False).add_argument("rest", nargs=argparse.REMAINDER)
    p_bench = sub.add_parser("bench", help="benchmarks that print their figures")
    p_bench.add_argument("what", help="sim | train | node | bridge | perception | twin (lhd bench twin --help)")
    p_bench.add_argument("--cycles", type=pos_int, default=1000, help="node: policy cycles measured (10 Hz)")
    p_bench.add_argument("--vs-sb3", action="store_true", help="train: also time Stable-Baselines3's DDPG")
    p_bench.add_argument("--seconds", type=float, default=4.0, help="bridge: latency measurement time")
    p_bench.add_argument("--json", action="store_true", help="one JSON line of the figures instead of the table")
    p_bench.add_argument("--steps", type=pos_int, default=None, help="sim, train: steps timed (default 3000; "
                         "sim --ros 1000)")
    p_bench.add_argument("--ros", action="store_true", help="sim: also through a lockstep sim node over DDS "
                         "(LhdLoadingRos-v0), next to the in-process figure")
    p_bench.add_argument("--seed", type=nonneg_int, default=0, help="sim, train: the episodes' seed")
    p_bench.add_argument("--rounds", type=pos_int, default=3, help="alternating runs; the best of each is reported")
    p_bench.add_argument("--config", default=None, help="parameter file (default: config/lhd_params.yaml)")
    p_bench.add_argument("--jobs", type=int, default=1, help="train: time N processes at once, as a study runs "
                         "its trials, and project the whole study (2 variants x 5 seeds) N at a time")
    p_bench.add_argument("--randomize", action="store_true", help="train: with domain randomisation (lhd train "
                         "--randomize)")
    p_sweep = sub.add_parser("sweep", help="a study (variants x seeds x randomisation x overrides) on Ray; "
                             "resumable; run folders for lhd report")
    p_sweep.add_argument("study", help="study file (YAML; lhd_loading_ros/learning/sweep.py, docs/training.md)")
    p_sweep.add_argument("--address", help="a running Ray cluster (default: a local Ray on this machine)")
    p_sweep.add_argument("--jobs", type=int, default=None, help="local Ray: trials at once (default or 0: all cores)")
    p_train = sub.add_parser("train", help="train a DDPG loading policy (the paper's protocol)")
    p_train.add_argument("--variant", choices=["rld", "rlc"], required=True)
    p_train.add_argument("--seed", type=nonneg_int, default=None, help="the run's seed (default 0)")
    p_train.add_argument("--seeds", help="several seeds in parallel processes, e.g. 0-4 or 0,2,5")
    p_train.add_argument("--jobs", type=int, default=0, help="parallel processes for --seeds (default 0: one per core)")
    p_train.add_argument("--steps", type=pos_int, default=None, help="environment steps (default: training.total_steps)")
    p_train.add_argument("--out", help="run directory (default runs/<variant>/seed_<N>; with --seeds, the parent)")
    p_train.add_argument("--config", default=None)
    p_train.add_argument("--env", choices=["local", "ros"], default="local",
                         help="local: the in-process environment; ros: lockstep sim nodes over DDS (--namespaces)")
    p_train.add_argument("--namespaces", help="--env ros: the sim nodes' namespaces, comma-separated (e.g. "
                         "/sim0,/sim1; '/' for the un-namespaced node)")
    p_train.add_argument("--ros-timeout", type=float, default=30.0, help="--env ros: seconds to wait for a sim node")
    p_train.add_argument("--no-resume", dest="resume", action="store_false",
                         help="start over even if a checkpoint exists; the previous run's files (checkpoints, best/, "
                              "final/, run.json, logs) move to previous_<UTC time>/ in the run folder, nothing deleted")
    p_train.add_argument("--keep-checkpoint", type=int, action="append", default=[], metavar="STEP",
                         help="also keep the checkpoint of this step as checkpoint_step<STEP>.pt (repeatable), for "
                              "--branch-from")
    p_train.add_argument("--branch-from", metavar="CHECKPOINT",
                         help="start a new --out from a kept checkpoint of the same variant, seed and config hash "
                              "(with --seeds: a file name under each seed's directory of another run, e.g. "
                              "runs/x/seed_{seed}/checkpoint_step250000.pt) and go on under this --config: a late "
                              "change of the training schedule compared pairwise at the cost of the remaining steps")
    p_train.add_argument("--no-progress", dest="progress", action="store_false")
    p_train.add_argument("--randomize", action="store_true",
                         help="domain randomisation (config section randomization: slope-estimate error, sensor noise, "
                              "dropouts, actuator delay, material, tyre friction, start pose; docs/training.md)")
    p_eval = sub.add_parser("eval", help="evaluate an exported policy on the simulator")
    p_eval.add_argument("--controller", choices=["actor", "tampier"], default="actor",
                        help="actor: an exported policy (--policy); tampier: the Tampier-style heuristic baseline")
    p_eval.add_argument("--policy", help="policy directory (actor.npz + policy.json); required for --controller actor. "
                        "An actor shipped with its own lhd_params.yaml (rld_drift_confirm, rld_machine, rlc_gains, the *_twin*, *_steep, *_told_* ones...: those with a lhd_params.yaml in their folder; policies/README.md) needs --config DIR/lhd_params.yaml")
    p_eval.add_argument("--slopes", default=None, help="tampier: pile slopes, degrees (default 15,20,25,30)")
    p_eval.add_argument("--material", choices=["both", "homogeneous", "nonhomogeneous"], default=None,
                        help="tampier: pile material (default both)")
    p_eval.add_argument("--time-limit", type=float, default=None,
                        help="tampier: s per attempt (default 10, the paper's real-world timeout; 0: the environment's)")
    p_eval.add_argument("--tampier-config", help="tampier: thresholds file (default config/tampier.yaml)")
    p_eval.add_argument("--episodes", type=int, default=120, help="attempts (default 120, the paper's evaluation)")
    p_eval.add_argument("--seed", type=nonneg_int, default=2_000_000, help="evaluation seed (training evaluates on 1,000,000)")
    p_eval.add_argument("--deploy-filter", action="store_true", help="RLC: apply the deployment filter, as on the machine")
    p_eval.add_argument("--run-refused", action="store_true",
                        help="run the episodes whose told slope (pile + the drawn LiDAR error) lies outside the actor's "
                             "trained range with the slope observation clipped, as every figure before 2026-11-29 "
                             "(twelfth session) did; by default they are not run and count as refused, as the policy "
                             "node and the supervisor refuse them on the machine")
    p_eval.add_argument("--stress", choices=list(STRESS_CASES), default=None,
                        help="actor: every episode under a named stress case (placement: heading +-3 deg, lip +-5 cm "
                             "off axis, camera noise/dropouts/delay, 100 ms actuator dead time; sensors; delay; light / dense gravel: "
                             "the density range's ends; rocky: every pile with randomization.rocks_max rocks; rough: every pile's face "
                             "with a 3 cm relief, the policy told the scanned slice's slope; slow_drive: the wheels at 80 %% of the commanded "
                             "speed; slow_hydraulics: boom and bucket at 75 %% of the commanded rates; cohesive: moist gravel "
                             "with fines, 1,500 Pa of cohesion; dense_placement: placement in front of dense gravel, the pair that "
                             "failed where each alone passed; rest: every attempt from rest with the tip in the pile, "
                             "as on the machine; machine: placement, rest and rough at once, how an attempt on the "
                             "machine goes; calibration: the boom and bucket angle sensors +-2 deg off their zero, the "
                             "tip, its pitch and the end test from the measured angles; its four sign pairs take 32 "
                             "episodes, 32/32/32/24 of 120; arm_noise: the boom and bucket angles read with 0.1 deg of "
                             "noise in 4,096 counts a turn, the rates the Due's differences of them over 0.1 s; "
                             "rest_bridge: rest with the drift flag the bridge gives, over a control period ending 0-140 "
                             "ms before each observation (its window ends at the newest camera image); machine_bridge: "
                             "machine with that flag)")
    p_eval.add_argument("--randomize", action="store_true",
                        help="actor: every episode under drawn conditions (config section randomization): how the "
                             "actor fares when the machine differs from the simulator")
    p_eval.add_argument("--zones", choices=list(EVAL_ZONES), default="pile", help="actor: " + ZONES_HELP)
    p_eval.add_argument("--zones-density", type=float, default=None, metavar="KG_M3", help=ZONES_DENSITY_HELP)
    p_eval.add_argument("--config", default=None)
    p_eval.add_argument("--json", action="store_true")
    p_exp = sub.add_parser("experiment", help="the paper's experiments in simulation")
    p_exp_sub = p_exp.add_subparsers(dest="experiment", required=True)
    p_paper = p_exp_sub.add_parser("paper", help="controllers x slopes x materials, and the slope-error table")
    p_paper.add_argument("--episodes", type=int, default=10, help="attempts per cell (default 10)")
    p_paper.add_argument("--out", default="runs/experiment_paper", help="folder for tables, CSV and figures")
    p_paper.add_argument("--jobs", type=int, default=0, help="processes (0: one per core)")
    p_paper.add_argument("--controllers", default="rld,rlc,tampier,scripted,teacher")
    p_paper.add_argument("--slopes", default="15,20,25,30", help="pile slopes of table (a), degrees")
    p_paper.add_argument("--materials", default="homogeneous,nonhomogeneous")
    p_paper.add_argument("--errors", default="-15,-10,-5,0,5,10,15",
                         help="slope errors (told - true) of table (b) on 15 and 30 deg piles, degrees")
    p_paper.add_argument("--rld", help="RLD policy directory (default policies/rld)")
    p_paper.add_argument("--rlc", help="RLC policy directory (default policies/rlc)")
    p_paper.add_argument("--seed", type=nonneg_int, default=3_000_000)
    p_paper.add_argument("--stress", choices=list(STRESS_CASES), default=None,
                         help="every attempt of every controller under a named stress case of lhd eval --stress "
                              "(light: dry, loose gravel, the density the bucket's 30 kg rating implies); the "
                              "controllers meet the same piles and conditions; the camera's and LiDAR's noise reaches the RL "
                              "actors only, the arm sensors' errors and the bridge's drift flags (rest_bridge, "
                              "machine_bridge) every controller")
    p_paper.add_argument("--zones", choices=list(EVAL_ZONES), default="pile", help=ZONES_HELP)
    p_paper.add_argument("--zones-density", type=float, default=None, metavar="KG_M3", help=ZONES_DENSITY_HELP)
    p_paper.add_argument("--config", default=None)
    p_paper.add_argument("--json", action="store_true")
    p_report = sub.add_parser("report", help="aggregate training runs across seeds")
    p_report.add_argument("runs", nargs="+", help="run directories, or parents holding seed_*/")
    p_report.add_argument("--plot", help="write the training curves (PNG) here")
    p_report.add_argument("--json", action="store_true")
    p_report.add_argument("--held-out", metavar="CONDITIONS",
                          help="also evaluate each run's final actor on the held-out piles (seed 2,000,000) under these "
                               "comma-separated conditions: nominal, randomized, " + ", ".join(STRESS_CASES))
    p_report.add_argument("--episodes", type=int, default=120, help="--held-out: episodes per actor and condition")
    p_report.add_argument("--zones", choices=list(EVAL_ZONES), default="pile", help="--held-out: " + ZONES_HELP)
    p_report.add_argument("--zones-density", type=float, default=None, metavar="KG_M3",
                          help="--held-out: " + ZONES_DENSITY_HELP)
    p_report.add_argument("--config", default=None, help="--held-out: parameter file (default config/lhd_params.yaml)")
    p_report.add_argument("--jobs", type=int, default=0,
                          help="--held-out: processes (default 0: one per core); the figures do not depend on it")
    p_ship = sub.add_parser("ship", help="pick a variant's median seed (final actors, held-out evaluation), "
                                        "write policies/<variant>")
    p_ship.add_argument("--variant", choices=["rld", "rlc"], required=True)
    p_ship.add_argument("runs", help="directory holding seed_*/ runs of this variant")
    p_ship.add_argument("--out", help="default policies/<variant>")
    p_ship.add_argument("--episodes", type=int, default=120)
    p_ship.add_argument("--select", choices=["median", "best", "best-final"], default="median",
                        help="median: the median seed's final actor (default); best: the best seed's best checkpoint; "
                             "best-final: the best seed's final actor, its table on piles the selection never saw")
    p_ship.add_argument("--config", default=None)
    p_ship.add_argument("--max-tilt-rate", type=float, default=None,
                        help="leave out seeds whose actor lifts the machine's rear over 5 deg in more than this share "
                             "of its held-out attempts (e.g. 0.05); default: no gate")
    p_mjcf = sub.add_parser("mjcf", help="write the MJCF of the scaled LHD generated from the parameter file")
    p_mjcf.add_argument("--out", help="file to write (default: print)")
    p_mjcf.add_argument("--config", default=None)
    p_cfg = sub.add_parser("config", help="parameter file tools: config check [PATH]",
                           description="lhd config check [PATH]: validate an lhd_params.yaml (the paper's table, "
                                       "machine, pile, simulator, task and training parameters) as every entry point "
                                       "loads it. Prints 'PATH: ok' and exits 0, or lists every problem (the key and "
                                       "the expected type and range) and exits 1. The ROS parameter files "
                                       "(config/*_node.yaml, real_machine.yaml) are checked by the nodes at start.")
    p_cfg.add_argument("action", choices=["check"], help="check: validate the file")
    p_cfg.add_argument("path", nargs="?", help="parameter file (default: $LHD_CONFIG, else config/lhd_params.yaml)")
    if argv[:1] == ["demo"]:
        from lhd_loading_ros.cli.launcher import main as up_main

        return up_main(argv[1:], demo=True)
    if argv[:2] == ["up", "sim"]:
        from lhd_loading_ros.cli.launcher import main as up_main

        return up_main(argv[2:])
    if argv[:2] == ["up", "twin"]:
        from lhd_loading_ros.cli.up_twin import main as twin_main

        return twin_main(argv[2:])
    if argv[:2] == ["bench", "twin"]:
        from lhd_loading_ros.cli.bench_twin import main as bench_twin_main

        return bench_twin_main(argv[2:])
    if argv[:2] == ["up", "real"]:
        from lhd_loading_ros.cli.up_real import main as real_main

        return real_main(argv[2:])
    groups = {
        "up": ("lhd up sim [--policy DIR | --controller tampier|teacher] [--slope DEG | --slopes ...] [--episodes N]: "
               "the sim node and the policy node over DDS",
               "lhd up real --port DEV [--controller rld|rlc|tampier|teacher|teleop]: the real-machine stack",
               "lhd up twin [--controller ...] [--slopes ...] [--episodes N]: the real-machine stack against the "
               "simulator as the Due"),
        "attempt": ("lhd attempt mass KG [--attempt N] [--run-dir DIR]: record the weighed mass of an attempt",),
        "validate": ("lhd validate physics [--plots DIR] [--json] [--quick] [--config F]: the simulator's physics "
                     "next to independent hand-calculation references",),
    }
    if len(argv) == 2 and argv[0] in groups and argv[1] in ("-h", "--help"):
        # a command group's help: its subcommands (each has its own --help), exit 0 as argparse's --help does
        print(f"usage: lhd {argv[0]} SUBCOMMAND ...   (lhd {argv[0]} SUBCOMMAND --help for its options)\n")
        print("\n".join(f"  {line}" for line in groups[argv[0]]))
        return 0
    if argv[:1] == ["up"]:
        print("lhd up: expected `lhd up sim [--policy DIR] [--slope DEG] [--episodes N]`, "
              "`lhd up real --port DEV [--controller rld|rlc|tampier|teacher|teleop]` or `lhd up twin [--slopes ...]`",
              file=sys.stderr)
        return 2
    if argv[:1] == ["echo"]:
        from lhd_loading_ros.cli.echo import main as echo_main

        return echo_main(argv[1:])
    if argv[:1] in (["arm"], ["abort"], ["attempts"]) or argv[:2] == ["attempt", "mass"]:
        from lhd_loading_ros.cli import attempts

        if argv[0] == "attempt":
            return attempts.attempt_mass_main(argv[2:])
        return {"arm": attempts.arm_main, "abort": attempts.abort_main, "attempts": attempts.main}[argv[0]](argv[1:])
    if argv[:1] == ["attempt"]:
        print("lhd attempt: expected `lhd attempt mass KG [--attempt N] [--run-dir DIR]`", file=sys.stderr)
        return 2
    if argv[:1] == ["replay"]:
        from lhd_loading_ros.cli.replay import main as replay_main

        return replay_main(argv[1:])
    if argv[:1] == ["bag"]:
        from lhd_loading_ros.cli.bag import main as bag_main

        return bag_main(argv[1:])
    if argv[:2] == ["validate", "physics"]:
        from lhd_sim_node.validate import main as validate_main   # the simulator only where it runs

        return validate_main(argv[2:])
    if argv[:1] == ["validate"]:
        print("lhd validate: expected `lhd validate physics [--plots DIR] [--json] [--quick] [--config F]`",
              file=sys.stderr)
        return 2
    if argv[:1] == ["estop"]:
        from lhd_loading_ros.cli.estop import main as estop_main

        return estop_main(argv[1:])
    args = ap.parse_args(argv)
    if args.cmd == "bench":
        return _bench(args)
    if args.cmd == "train":
        return _train(args)
    if args.cmd == "eval":
        return _eval(args)
    if args.cmd == "report":
        return _report(args)
    if args.cmd == "sweep":
        return _sweep(args)
    if args.cmd == "experiment":
        return _experiment(args)
    if args.cmd == "ship":
        from lhd_loading_ros.learning.ship import ship

        try:
            res = ship(args.variant, args.runs, args.out or f"policies/{args.variant}", args.episodes, args.config,
                       select=args.select, max_tilt_rate=args.max_tilt_rate)
        except (FileNotFoundError, ValueError) as exc:
            print(f"lhd ship: {exc}", file=sys.stderr)
            return 1
        print(f"shipped {res['shipped_from']} -> {args.out or f'policies/{args.variant}'}")
        return 0
    if args.cmd == "config":
        return _config(args)
    if args.cmd == "mjcf":
        return _mjcf(args)
    ap.error(f"unknown command {args.cmd}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
