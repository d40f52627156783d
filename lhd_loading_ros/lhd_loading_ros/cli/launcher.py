"""`lhd up sim`: the sim node and the policy node as separate processes on real DDS (what
launch/sim_loading.launch.py does where `ros2 launch` exists), watched until the asked
episodes are done, then stopped cleanly (the policy first, by SIGTERM). Ctrl-C or SIGTERM stop
both; children also die with the launcher (PR_SET_PDEATHSIG), so no orphan is left behind.

Started in the background of a script, the shell makes it ignore SIGINT (the rule for
background jobs, so that Ctrl-C to the script does not reach them); the launcher keeps that
rule, stops cleanly on SIGTERM (`kill`), and takes no signal handler from rclpy, which would
override the ignored SIGINT and shut its ROS context down under it.

Logs: the nodes' output goes to a temporary folder that is removed at exit; after a failure
(a node exited, a timeout) the folder is kept and the message says where. `--log-dir` keeps
the logs in a folder of your choice.

`lhd demo` is `lhd up sim` on piles of 15, 20, 25 and 30 deg (homogeneous, 3 attempts each)
with the shipped RLD actor, printing the paper's results-table layout.
"""
from __future__ import annotations

import argparse
import ctypes
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from lhd_loading_ros.task import json_out
from lhd_loading_ros.cli.argtypes import nonneg_int
from lhd_loading_ros.task.metrics import EpisodeResult, result_from_status

PR_SET_PDEATHSIG = 1


def _die_with_parent():
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass
    os.setsid()


def param_args(params: dict) -> list[str]:
    """`-p name:=value` for each parameter; an empty string as YAML's '': `-p policy_dir:=` is a
    parse error that ended the node (`lhd up real --controller tampier|teleop` could not start: a
    review, 2026-11-28)."""
    out = []
    for k, v in params.items():
        out += ["-p", f"{k}:={v if v != '' else repr('')}"]
    return out


def child_env(log_dir: Path) -> dict:
    """The environment of a node the launcher starts: unbuffered output, and rcl's own log files in the launcher's
    log folder (ROS_LOG_DIR), beside the node's console log, unless the user set ROS_LOG_DIR or ROS_HOME: every
    node had left them in ~/.ros/log (43 MB on a machine that ran the suite: a review)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if "ROS_LOG_DIR" not in env and "ROS_HOME" not in env:
        env["ROS_LOG_DIR"] = str(Path(log_dir) / "rcl")
    return env


class Child:
    """A node process: `python -m module --ros-args [ros_args] -p k:=v ...`, output to
    log_dir/<name>.log when quiet."""

    def __init__(self, name: str, module: str, params: dict, log_dir: Path, quiet: bool, ros_args=()):
        args = [sys.executable, "-m", module, "--ros-args", *ros_args, *param_args(params)]
        self.name = name
        self.log_path = log_dir / f"{name}.log"
        self._log = open(self.log_path, "w")
        out = self._log if quiet else None
        self.proc = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT if quiet else None,
                                     env=child_env(log_dir), preexec_fn=_die_with_parent)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 10.0) -> int:
        """SIGTERM (run_node's orderly stop; unlike SIGINT, never inherited as ignored from a
        script's background job), SIGKILL after `timeout`."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
            except ProcessLookupError:
                pass
        self._log.close()
        return self.proc.returncode


def log_tail(text: str, limit: int = 3000) -> str:
    """The end of a node's log, whole lines only (a cut inside a line or a word reads as garbage),
    and the last error's first line when the cut left it out (an exception message longer than
    the tail: the reader sees what went wrong before the details)."""
    if len(text) <= limit:
        return text
    tail = text[-limit:]
    tail = tail[tail.find("\n") + 1:] if "\n" in tail else tail
    head = ""
    for line in text[:len(text) - len(tail)].splitlines():
        if line and not line[0].isspace() and not line.startswith("Traceback"):
            head = line          # the last unindented line before the cut: the start of the message
    return (f"{head}\n  ...\n" if head else "  ...\n") + tail


def check_children(children: list, quiet: bool = True) -> None:
    """RuntimeError naming the first node process that has exited, with its log's tail (when its
    output went to a log file, `quiet`)."""
    for c in children:
        if not c.alive():
            tail = log_tail(c.log_path.read_text()) if quiet else ""
            raise RuntimeError(f"{c.name} exited with status {c.proc.returncode}:\n{tail}")


def stop_stack(children: list, node) -> None:
    """Stop the node processes in reverse start order (what commands the machine before what it
    commands), then the launcher's own node and its ROS context."""
    import rclpy

    for c in reversed(children):
        c.stop()
    node.destroy_node()
    if rclpy.ok():
        rclpy.shutdown()


class _StopOnSignals:
    """SIGTERM, and SIGINT and SIGHUP unless ignored when we started (a script's background job,
    nohup), set `event`; the previous handlers come back on exit. Only the flag is touched in the
    handler, so the stop runs in order from the main loop (as in ros/run.py's run_node). SIGHUP (the
    terminal closed, an SSH session dropped) used to kill the launcher at once: its nodes then all
    got SIGTERM together, out of order, and one was once left hung (a review, 2026-11-28)."""

    def __init__(self, event: threading.Event):
        self.event, self.previous = event, {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
                if signal.getsignal(sig) is not signal.SIG_IGN:
                    self.previous[sig] = signal.signal(sig, lambda *_: self.event.set())
        return self

    def __exit__(self, *exc):
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)


def namespace_ros_args(namespace: str | None, use_sim_time: bool) -> list[str]:
    """--ros-args for both nodes: the namespace (every /lhd topic moves under it, as
    ros/params.topic_prefix says) and, for use_sim_time, /clock remapped to the namespace's
    clock, which is where the sim node publishes it under a namespace."""
    args = []
    if namespace:
        args += ["-r", f"__ns:={namespace}"]
        if use_sim_time:
            args += ["-r", f"/clock:={namespace}/clock"]
    if use_sim_time:
        args += ["-p", "use_sim_time:=true"]
    return args


# what `lhd up sim` / `lhd demo --controller` start in the policy node (its `controller` parameter)
SIM_CONTROLLERS = ("actor", "tampier", "teacher")
CONTROLLER_LABELS = {"tampier": "Tampier-style heuristic", "teacher": "demonstrations' teacher"}


def slope_range_problem(slopes, cfg: dict, flag: str, config_name: str) -> str:
    """Why these pile slopes cannot be loaded under `cfg` ("" if they can): each must lie in the
    pile range the parameter file gives (paper.episode alpha_min_deg..alpha_max_deg, the range its
    actors were trained on), as the sim node and the environment require; refused, not clipped."""
    ep = cfg["paper"]["episode"]
    lo, hi = float(ep["alpha_min_deg"]), float(ep["alpha_max_deg"])
    bad = [s for s in slopes if not math.isfinite(s)]
    if bad:
        return f"{flag} {' '.join(f'{s:g}' for s in bad)}: not a finite number; expected slopes in degrees, e.g. 20"
    out = [s for s in slopes if not lo - 1e-9 <= s <= hi + 1e-9]
    if not out:
        return ""
    return (f"{flag} {' '.join(f'{s:g}' for s in out)}: outside the pile range [{lo:g}, {hi:g}] deg of {config_name} "
            f"(paper.episode.alpha_min_deg / alpha_max_deg, the range its actors were trained on); expected slopes in it")


class EpisodeWatcher:
    """The launcher's reading of the sim node's /episode statuses: one result per ended episode.

    The sim node publishes a status every control step (keep-last 10 on its side). up_sim reads them
    with a deep history (ros.qos.WATCH_QOS) so that a busy launcher still gets every end; should one still be
    lost, the last status (all episodes done) carries `episodes_done`: check_complete compares, so a
    lost end is an error that names the episodes, never a shorter list of results returned as if it
    were all of them (`lhd up sim --episodes 2` once exited 0 with one, when the reader's history was 10)."""

    def __init__(self, on_episode=None):
        self.on_episode = on_episode
        self.results: dict[int, EpisodeResult] = {}
        self.aborted: set[int] = set()
        self.done = {"all": False, "heard": False}
        self.final: dict | None = None

    def on_status(self, kv: dict) -> None:
        self.done["heard"] = True
        state = kv.get("state", "running")
        if state == "running":
            return
        ep = int(kv["episode"])
        if state == "aborted":
            self.aborted.add(ep)        # no result: MuJoCo found the state unstable; not counted by the node
        elif ep not in self.results:
            self.results[ep] = result_from_status(kv)
            if self.on_episode:
                self.on_episode(ep, self.results[ep])
        if kv.get("all_done") == "True":
            self.done["all"] = True
            self.final = kv

    def check_complete(self) -> None:
        """After the all-done status: raise RuntimeError when fewer ended episodes were heard than the
        sim node counted, naming the episodes whose end was not heard."""
        from lhd_loading_ros.ros.qos import WATCH_QOS

        if self.final is None:
            raise RuntimeError("check_complete before the sim node's all-done status")
        counted = int(self.final["episodes_done"])
        if len(self.results) >= counted:
            return
        last = int(self.final["episode"])
        missing = sorted(set(range(last + 1)) - set(self.results) - self.aborted)
        raise RuntimeError(f"the sim node ended {counted} episodes but this launcher heard the end of "
                           f"{len(self.results)} ({sorted(self.results)}); not heard: episode(s) {missing} (the "
                           "launcher's process was starved longer than its reader's history of /episode, "
                           f"{WATCH_QOS.depth} statuses, lasts). The episodes ran; their results are in the sim "
                           "node's log. Rerun on a less loaded machine, or in realtime mode")


def up_sim(policy: str | None, slopes: list[float] | None, episodes: int, material: str, mode: str, seed: int,
           config: str | None, quiet: bool = True, log_dir: Path | None = None, timeout_s: float = 0.0,
           on_episode=None, namespace: str | None = None, use_sim_time: bool = False,
           controller: str = "actor") -> list[EpisodeResult]:
    """Run sim node + policy node until `episodes` episodes ended (0: until Ctrl-C / SIGTERM).
    Logs go to `log_dir` (kept) or to a temporary folder, removed unless something failed."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.signals import SignalHandlerOptions

    from lhd_loading_ros.ros.params import discovery_wait_s
    from lhd_loading_ros.ros.qos import WATCH_QOS

    keep_logs = log_dir is not None
    log_dir = Path(log_dir) if keep_logs else Path(tempfile.mkdtemp(prefix="lhd_up_"))
    log_dir.mkdir(parents=True, exist_ok=True)
    prefix = namespace or "/lhd"
    common = {"config": config} if config else {}
    ros_args = namespace_ros_args(namespace, use_sim_time)
    sim_params = {**common, "mode": mode, "seed": seed, "episodes": episodes, "material": material,
                  "auto_reset": "true", "reset_delay": 0.5}
    if slopes:
        sim_params["slopes_deg"] = ",".join(f"{s:g}" for s in slopes)
    pol_params = {**common, "trigger": "lockstep" if mode == "lockstep" else "timer",
                  "input_qos": "reliable" if mode == "lockstep" else "sensor_data"}
    if controller != "actor":
        pol_params["controller"] = controller
    elif policy:
        pol_params["policy_dir"] = str(Path(policy).resolve())
    stop = threading.Event()
    watcher = EpisodeWatcher(on_episode)
    seen = watcher.results
    done = watcher.done

    def on_status(msg):
        watcher.on_status({k.key: k.value for k in msg.values})

    def spin_checked(children, t0):
        rclpy.spin_once(node, timeout_sec=0.1)
        check_children(children, quiet)
        if timeout_s and time.monotonic() - t0 > timeout_s:
            raise TimeoutError(f"episodes not done after {timeout_s:.0f} s")

    children: list[Child] = []
    failed = True
    with _StopOnSignals(stop):
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("lhd_up")
        try:
            # another simulator, bridge or policy on this domain and namespace would mix its
            # topics with ours
            t_check = time.monotonic() + discovery_wait_s()      # DDS discovery of existing participants
            busy = {}
            while not busy and time.monotonic() < t_check and not stop.is_set():
                rclpy.spin_once(node, timeout_sec=0.1)
                busy = {t: n for t in (f"{prefix}/{name}" for name in ("joint_states", "odom", "cmd", "episode"))
                        if (n := node.count_publishers(t))}
            if busy:
                raise RuntimeError(f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')} already has publishers on "
                                   f"{busy}: another LHD simulator, bridge or policy is running there. Stop it, or set "
                                   "ROS_DOMAIN_ID to a free domain (or --namespace to a free namespace) for this run")
            # a deep history on this side: the sim node publishes a status every control step (keep-last 10 on
            # its side), and while this process is busy (a slow on_episode, a loaded machine) the DDS thread keeps
            # receiving; with 10 here an episode's end was replaced by the next one's statuses in lockstep
            node.create_subscription(DiagnosticStatus, f"{prefix}/episode", on_status, WATCH_QOS)
            # the sim node first; the policy node once this watcher hears the sim's episode status,
            # so no episode can end before the watcher is matched (lockstep episodes take 0.1 s).
            # The sim's episode waits for the first command, so the policy's start-up is not
            # counted in the first attempt.
            t0 = time.monotonic()
            if not stop.is_set():
                children.append(Child("sim_node", "lhd_sim_node.sim_node", sim_params, log_dir, quiet, ros_args))
            while not done["heard"] and not stop.is_set():
                spin_checked(children, t0)
                if time.monotonic() - t0 > 120:
                    raise TimeoutError("no episode status from the sim node after 120 s")
            if not stop.is_set():
                children.append(Child("policy_node", "lhd_loading_ros.nodes.policy_node", pol_params, log_dir, quiet,
                                      ros_args))
            while not done["all"] and not stop.is_set():
                spin_checked(children, t0)
            if done["all"]:
                watcher.check_complete()
            failed = False
        except (RuntimeError, TimeoutError) as exc:
            if children and quiet:
                raise type(exc)(f"{exc}\n(node logs kept in {log_dir})") from None
            raise
        finally:
            stop_stack(children, node)       # the policy first: the machine gets no command after the sim stops
            if not keep_logs and not (failed and quiet and children):
                shutil.rmtree(log_dir, ignore_errors=True)
    if stop.is_set():
        print("\ninterrupted: nodes stopped", file=sys.stderr)
    return [seen[k] for k in sorted(seen)]


def count_namespaces(count: int, base: str | None) -> list[str]:
    """The namespaces of `lhd up sim --count N`: <base>0 .. <base>N-1 (base /sim by default)."""
    if count < 1:
        raise ValueError(f"--count must be >= 1, got {count}")
    b = "/" + (base or "/sim").strip("/")
    return [f"{b}{i}" for i in range(count)]


def up_sim_nodes(namespaces: list[str], mode: str, seed: int, config: str | None, quiet: bool = True,
                 log_dir: Path | None = None, on_ready=None, run_s: float = 0.0) -> int:
    """N sim nodes, one per namespace, for learners (`lhd train --env ros --namespaces ...`): no
    policy node, no episode limit; they run until Ctrl-C / SIGTERM (or `run_s` seconds) and are
    then stopped. A node that exits ends all of them (status 1, its log's tail printed).
    on_ready(namespaces) once every node's /episode status is heard."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.signals import SignalHandlerOptions

    from lhd_loading_ros.ros.params import discovery_wait_s
    from lhd_loading_ros.ros.qos import STATUS_QOS

    keep_logs = log_dir is not None
    log_dir = Path(log_dir) if keep_logs else Path(tempfile.mkdtemp(prefix="lhd_up_"))
    log_dir.mkdir(parents=True, exist_ok=True)
    common = {"config": config} if config else {}
    stop = threading.Event()
    heard: set[str] = set()
    children: list[Child] = []
    failed = True
    with _StopOnSignals(stop):
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("lhd_up_sims")
        try:
            t_check = time.monotonic() + discovery_wait_s()      # DDS discovery: a namespace already served is refused
            busy = {}
            while not busy and time.monotonic() < t_check and not stop.is_set():
                rclpy.spin_once(node, timeout_sec=0.1)
                busy = {f"{ns}/cmd": n for ns in namespaces if (n := node.count_publishers(f"{ns}/episode"))}
            if busy:
                raise RuntimeError(f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}: a sim node already serves "
                                   f"{sorted(busy)}; stop it or give another --namespace base")
            for i, ns in enumerate(namespaces):
                def on_status(msg, ns=ns):
                    heard.add(ns)
                node.create_subscription(DiagnosticStatus, f"{ns}/episode", on_status, STATUS_QOS)
                params = {**common, "mode": mode, "seed": seed + 1_000_000 * i, "auto_reset": "true"}
                children.append(Child(f"sim_node{i}", "lhd_sim_node.sim_node", params, log_dir, quiet,
                                      namespace_ros_args(ns, False)))
            t0 = time.monotonic()
            ready = False
            while not stop.is_set():
                rclpy.spin_once(node, timeout_sec=0.1)
                check_children(children, quiet)
                if not ready and len(heard) == len(namespaces):
                    ready = True
                    if on_ready:
                        on_ready(namespaces)
                if not ready and time.monotonic() - t0 > 120:
                    raise TimeoutError(f"no episode status after 120 s from {sorted(set(namespaces) - heard)}")
                if run_s and ready and time.monotonic() - t0 > run_s:
                    break
            failed = False
        except (RuntimeError, TimeoutError) as exc:
            if children and quiet:
                raise type(exc)(f"{exc}\n(node logs kept in {log_dir})") from None
            raise
        finally:
            stop_stack(children, node)
            if not keep_logs and not (failed and quiet and children):
                shutil.rmtree(log_dir, ignore_errors=True)
    if stop.is_set():
        print("\ninterrupted: sim nodes stopped", file=sys.stderr)
    return 0


def main(argv=None, demo: bool = False) -> int:
    ap = argparse.ArgumentParser(prog="lhd demo" if demo else "lhd up sim",
                                 description=("the main job: the sim node and the policy node over DDS load piles "
                                              "of 15, 20, 25 and 30 deg in turn, 12 attempts (3 per slope), then "
                                              "the paper's results table" if demo else
                                              "sim node + policy node over DDS"))
    ap.add_argument("--policy", help="policy directory (default: policies/rld, the shipped RLD actor)")
    ap.add_argument("--controller", choices=SIM_CONTROLLERS, default=None,
                    help="what the policy node runs: actor (--policy, the default), tampier (the Tampier-style "
                    "heuristic, config/tampier.yaml) or teacher (the training's demonstration maneuver on the end "
                    "zone, the parameter file's training.demo_*)")
    ap.add_argument("--slope", type=float, help="one slope for every episode, degrees (default: " +
                    ("the --slopes cycle 15 20 25 30)" if demo else "random)"))
    ap.add_argument("--slopes", type=float, nargs="+", help="cycle through these slopes, degrees" +
                    (" (default: 15 20 25 30)" if demo else ""))
    ap.add_argument("--episodes", type=int, default=12 if demo else 0,
                    help=("attempts in all, cycling through the slopes (default 12: 3 per slope; 0: until Ctrl-C, "
                          "not with --scripted)" if demo else "stop after N episodes (0: until Ctrl-C)"))
    ap.add_argument("--material", choices=["homogeneous", "nonhomogeneous", "random"],
                    default="homogeneous" if demo else "random",
                    help="pile material (default: homogeneous)" if demo else None)
    ap.add_argument("--mode", choices=["realtime", "lockstep"], default=None,
                    help="sim node mode (default realtime)" if demo else
                    "sim node mode (default realtime; lockstep with --count)")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--config", default=None)
    ap.add_argument("--namespace", help="run both nodes in this ROS namespace (their topics move from /lhd to it)"
                    + ("" if demo else "; with --count, the base of the sim nodes' namespaces (default /sim: /sim0, "
                                       "/sim1, ...)"))
    if not demo:
        ap.add_argument("--count", type=nonneg_int, default=0, help="start N sim nodes for learners, in namespaces "
                        "/sim0../simN-1, lockstep unless --mode says otherwise, no policy node; they run until "
                        "Ctrl-C (then `lhd train --env ros --namespaces /sim0,/sim1,...`)")
        ap.add_argument("--run-s", type=float, default=0.0, help=argparse.SUPPRESS)
    ap.add_argument("--use-sim-time", action="store_true", help="both nodes on the sim node's /clock")
    ap.add_argument("--log-dir", type=Path, help="keep the nodes' logs here (default: a temporary folder, "
                                                 "removed at exit unless a node failed)")
    ap.add_argument("--verbose", action="store_true", help="show the nodes' logs")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--scripted", action="store_true", help=argparse.SUPPRESS if not demo else
                    "the scripted maneuver on the simulator instead of the nodes (no ROS); honours --slope/--slopes, "
                    "--episodes, --material, --seed, --config and --json, refuses the nodes' flags")
    args = ap.parse_args(argv)
    if args.json:             # the JSON alone on stdout (cli/clean_stdout.py)
        from lhd_loading_ros.cli.clean_stdout import reserve_stdout

        reserve_stdout()
    if demo and args.scripted:
        from lhd_loading_ros.cli.demo import scripted_demo

        return scripted_demo(args, ap.prog)
    if args.episodes < 0:
        ap.error(f"--episodes must be >= 0, got {args.episodes}")
    count = getattr(args, "count", 0)
    if count:
        if count < 0 or count > 64:
            ap.error(f"--count must be in 1..64, got {count}")
        given = [f for f, v in (("--policy", args.policy), ("--controller", args.controller),
                                ("--slope", args.slope), ("--slopes", args.slopes),
                                ("--episodes", args.episodes), ("--use-sim-time", args.use_sim_time)) if v]
        if given:
            ap.error(f"--count starts sim nodes for learners only; {', '.join(given)} do not apply (the learner "
                     "sets each episode's seed and slope)")
        try:
            namespaces = count_namespaces(count, args.namespace)
            from rclpy.validate_namespace import validate_namespace

            for ns in namespaces:
                validate_namespace(ns)
        except Exception as exc:
            ap.error(f"--namespace {args.namespace!r}: {str(exc).splitlines()[0]}")

        def ready(nss):
            mode = args.mode or "lockstep"
            cfg = f" --config {args.config}" if args.config else ""
            hint = (f"train with\n  lhd train --variant rld --env ros --namespaces {','.join(nss)}{cfg}" if mode == "lockstep"
                    else "(realtime: for controllers on the wall clock; a learner needs --mode lockstep)")
            print(f"{len(nss)} sim nodes ({mode}) up in {', '.join(nss)}; {hint}\nCtrl-C or SIGTERM stops them",
                  flush=True)

        try:
            return up_sim_nodes(namespaces, args.mode or "lockstep", args.seed, args.config, quiet=not args.verbose,
                                log_dir=args.log_dir, on_ready=ready, run_s=args.run_s)
        except (RuntimeError, TimeoutError) as exc:
            print(f"{ap.prog}: {exc}", file=sys.stderr)
            return 1
    args.mode = args.mode or "realtime"
    if args.namespace:
        from rclpy.exceptions import InvalidNamespaceException
        from rclpy.validate_namespace import validate_namespace

        args.namespace = "/" + args.namespace.strip("/")
        try:
            validate_namespace(args.namespace)
        except InvalidNamespaceException as exc:
            ap.error(f"--namespace {args.namespace!r}: {str(exc).splitlines()[0].rstrip(':')}")
    slopes = args.slopes or ([args.slope] if args.slope is not None else ([15, 20, 25, 30] if demo else None))
    from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy
    from lhd_loading_ros.nodes.policy_node import default_policy_dir

    controller = args.controller or "actor"
    if controller != "actor" and args.policy:
        ap.error(f"--policy is the actor's; --controller {controller} runs no actor (drop --policy, or use "
                 "--controller actor)")
    policy = args.policy or str(default_policy_dir("rld"))
    from lhd_loading_ros.task.config import ConfigError, config_name, load_config

    try:
        cfg_checked = load_config(args.config)   # a bad parameter file is refused before any node starts
        if controller == "actor":
            pol = load_policy(policy)
            pol.check_config(cfg_checked)
            meta, label = pol.meta, f"{pol.variant.upper()} actor {policy}"
        else:
            meta = {"bucket_capacity": float(cfg_checked["task"]["bucket_capacity"])}
            label = CONTROLLER_LABELS[controller]
            if controller == "teacher":      # its setting is refused here as the node would refuse it
                from lhd_loading_ros.policy.teacher import TeacherSetting

                TeacherSetting.from_config(cfg_checked)
            else:
                from lhd_loading_ros.policy.tampier import load_tampier_config

                load_tampier_config()
    except (PolicyFileError, ConfigError, ValueError) as exc:     # bad input, as a bad option: status 2
        print(f"{ap.prog}: {exc}", file=sys.stderr)
        return 2
    if slopes:    # before any node starts: the sim node would refuse it too
        bad = slope_range_problem(slopes, cfg_checked, "--slopes" if args.slopes else "--slope",
                                  config_name(args.config))
        if bad:
            print(f"{ap.prog}: {bad}", file=sys.stderr)
            return 2

    def show(ep, r):
        if not args.json:
            print(f"episode {ep:3d}: {r.alpha_deg:4.1f} deg {r.material:<14} "
                  f"{'success' if r.success else ('end zone' if r.reached_end_zone else ('restricted zone' if r.failed else 'timeout')):<15} "
                  f"loaded {r.loaded:5.1f} kg  SL {r.success_level}  {r.elapsed_s:4.1f} s  "
                  f"drift front {r.front_drift_pct:4.1f} % rear {r.rear_drift_pct:4.1f} %", flush=True)

    if not args.json:
        print(f"{ap.prog}: sim node ({args.mode}) + policy node ({label}), "
              f"{args.episodes or 'unlimited'} episodes, Ctrl-C or SIGTERM stops", flush=True)
    t0 = time.monotonic()
    try:
        results = up_sim(policy, slopes, args.episodes, args.material, args.mode, args.seed, args.config,
                         quiet=not args.verbose, log_dir=args.log_dir, on_episode=show, namespace=args.namespace,
                         use_sim_time=args.use_sim_time, controller=controller)
    except (RuntimeError, TimeoutError) as exc:
        print(f"{ap.prog}: {exc}", file=sys.stderr)
        return 1
    if not results:
        return 0
    from lhd_sim_node.demo import format_table, table_rows

    rows = table_rows(results, slopes or sorted({round(r.alpha_deg) for r in results}), meta)
    if args.json:
        ok = sum(1 for r in results if r.to_dict()["success"])
        print(json_out.dumps({"success_rate": ok / len(results), "successes": ok, "attempts": len(results),
                          "rows": rows, "episodes": [r.to_dict() for r in results],
                          "controller": controller, "policy": policy if controller == "actor" else None,
                          "wall_s": time.monotonic() - t0}))
    else:
        what = f"{pol.variant.upper()} policy" if controller == "actor" else CONTROLLER_LABELS[controller].capitalize()
        print(format_table(rows, f"{what} through the ROS nodes ({args.mode}), {args.material} "
                                 f"material, {len(results)} attempts, {time.monotonic() - t0:.0f} s"))
    return 0
