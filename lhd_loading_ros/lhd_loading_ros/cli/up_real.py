"""`lhd up real`: the real-machine stack in one command (what
`ros2 launch lhd_loading_ros real_machine.launch.py` does on a full ROS install).

Starts, as separate processes on real DDS, in this order:
  bridge        lhd_hw_bridge.bridge_node      the Arduino Due on --port
  aruco         nodes.aruco_pose_node          /lhd/odom (v_x) from --camera-topic
  lidar         nodes.lidar_slope_node         /lhd/pile/slope + toe from --scan-topic
  end_zone      nodes.end_zone_node            /lhd/pile/end_zone + zones (LiDAR, or a surveyed file)
  supervisor    nodes.supervisor_node          /lhd/episode, /lhd/arm, the attempts CSV
  mux           nodes.cmd_mux_node             the only writer of /lhd/cmd (gated on the attempt)
  teleop        nodes.teleop_node              /joy -> /lhd/cmd/teleop (deadman, e-stop)
  controller    nodes.policy_node              RLD / RLC actor, the Tampier heuristic or the
                                               demonstrations' teacher, on /lhd/cmd/auto (none
                                               for --controller teleop)
  recorder      nodes.recorder_node            one rosbag2 per attempt under <run-dir>/bags
Then it prints the supervisor's preflight checklist and every attempt's events. With a
terminal on stdin: Enter arms an attempt, `a` aborts it, `m 23.4` records the weighed mass, `q`
quits. Without one, use `lhd arm`, `lhd abort`, `lhd attempt mass KG` from another shell.

Calibration (camera pose, LiDAR pose, marker, surveyed pile) comes from a ROS parameter file,
`--params-file` (default config/real_machine.yaml), passed to every node; the options below
override it. Ctrl-C or SIGTERM stop everything, the controller first and the bridge last (its
last frame to the Due is a stop frame); children die with the launcher (PR_SET_PDEATHSIG).
docs/real_machine.md is the guide.
"""
from __future__ import annotations

import argparse
import math
import os
import re
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import NamedTuple

from lhd_loading_ros.cli.launcher import Child, _StopOnSignals, check_children, stop_stack
from lhd_loading_ros.ros.params import discovery_wait_s
from lhd_loading_ros.ros.params_file import params_of

CONTROLLERS = ("rld", "rlc", "tampier", "teacher", "teleop")
ENDED = ("success", "failure", "timeout", "estop", "lost_input", "aborted")


def default_params_file() -> Path | None:
    """config/real_machine.yaml of the source tree, else the installed share copy."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "config" / "real_machine.yaml"
        if cand.is_file():
            return cand
    try:
        from ament_index_python.packages import get_package_share_directory

        cand = Path(get_package_share_directory("lhd_loading_ros")) / "config" / "real_machine.yaml"
        return cand if cand.is_file() else None
    except Exception:  # noqa: BLE001 - no ament index here
        return None


def stack(args, run_dir: Path) -> list[tuple[str, str, dict, list[str]]]:
    """(name, module, parameters, extra ros args) of every node, in start order."""
    if args.controller in ("rld", "rlc") and not args.policy:
        resolve_actor(args)          # check_args does it; a caller that skipped it gets the same actor
    common = {"config": args.config} if args.config else {}
    policy_dir = str(Path(args.policy).resolve()) if args.controller in ("rld", "rlc") else ""
    nodes = [
        ("bridge", "lhd_hw_bridge.bridge_node", {**common, "port": args.port}, []),
        ("aruco", "lhd_loading_ros.nodes.aruco_pose_node",
         {"image_topic": args.camera_topic, "camera_info_topic": args.camera_info_topic,
          "image_reliable": str(args.image_reliable).lower()}, []),
        ("lidar", "lhd_loading_ros.nodes.lidar_slope_node", {"scan_topic": args.scan_topic}, []),
        ("end_zone", "lhd_loading_ros.nodes.end_zone_node",
         {**common, **({"source": "surveyed", "surveyed_file": str(Path(args.end_zone).resolve())}
                       if args.end_zone != "lidar" else {"source": "lidar"})}, []),
        ("supervisor", "lhd_loading_ros.nodes.supervisor_node",
         {**common, "run_dir": str(run_dir), "controller": args.controller, "policy_dir": policy_dir,
          **({"slope_limits_deg": list(args.slope_limits)} if getattr(args, "slope_limits", None) else {}),
          "material": args.material, "attempt_timeout": args.attempt_timeout,
          "teleop_attempt_timeout": args.teleop_attempt_timeout,
          "required_listeners": required_listeners(args)}, []),
        ("mux", "lhd_loading_ros.nodes.cmd_mux_node", {**common}, []),
        ("teleop", "lhd_loading_ros.nodes.teleop_node", {**common, "mapping": args.joy_mapping}, []),
    ]
    if args.controller != "teleop":
        params = {**common, "trigger": "timer"}
        if args.controller in ("tampier", "teacher"):
            params["controller"] = args.controller
        else:
            params["policy_dir"] = policy_dir
        nodes.append(("controller", "lhd_loading_ros.nodes.policy_node", {**params, "cmd_topic": "cmd/auto"}, []))
    if args.record:
        nodes.append(("recorder", "lhd_loading_ros.nodes.recorder_node",
                      {"run_dir": str(run_dir), "storage": args.storage}, []))
    return nodes


def required_listeners(args) -> list[str]:
    """The stack's nodes that act on /lhd/episode: the supervisor arms only once each listens
    (an attempt armed within the first second, before the recorder had discovered the status,
    had no bag; before the mux and controller had, the machine would not move)."""
    names = ["lhd_cmd_mux"] + (["lhd_policy"] if args.controller != "teleop" else [])
    return names + (["lhd_recorder"] if args.record else [])


class Console:
    """The operator's keys (a terminal on stdin): Enter arms, `a` aborts, `m KG` records the
    weighed mass, `q` quits. Lines are read by a thread and handled in the main loop."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.lines: list[str] = []
        self._lock = threading.Lock()
        if enabled:
            threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        # a blocking read in a daemon thread: select() on the descriptor beside the buffered
        # sys.stdin left every line after the first of a burst (keys typed fast, a paste) in
        # Python's buffer until the next key came
        for line in sys.stdin:
            with self._lock:
                self.lines.append(line.strip())

    def take(self) -> list[str]:
        with self._lock:
            out, self.lines = self.lines, []
        return out


def make_run_dir(path: str | None, kind: str, prog: str) -> Path | None:
    """The run folder (default runs/<kind>/<UTC time>), created; None (the reason printed) when
    it cannot be."""
    run_dir = Path(path or Path("runs") / kind / datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S")).resolve()
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        print(f"{prog}: cannot create the run folder {run_dir}: {exc}", file=sys.stderr)
        return None
    return run_dir


def up_real(args) -> int:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import Float64
    from std_srvs.srv import Trigger

    from lhd_loading_ros.ros.qos import STATUS_QOS

    run_dir = make_run_dir(args.run_dir, "real", "lhd up real")
    if run_dir is None:
        return 2
    keep_logs = args.log_dir is not None
    log_dir = Path(args.log_dir) if keep_logs else run_dir / "logs"
    log_dir.mkdir(parents=True, exist_ok=True)
    kept = keep_earlier_logs(log_dir) if not keep_logs else None    # (a folder the user named is left alone)
    if kept:
        print(f"lhd up real: the node logs of an earlier run in this folder moved to {kept}", flush=True)
    params_file = Path(args.params_file) if args.params_file else default_params_file()
    ros_args = ["--params-file", str(params_file)] if params_file else []
    quiet = not args.verbose
    stop = threading.Event()
    state = {"episode": None, "state": None, "ended": 0, "preflight": None, "printed_preflight": None,
             "kv": {}, "link": {}, "record": {}, "record_failed": False}

    def on_status(msg):
        kv = {k.key: k.value for k in msg.values}
        state["kv"] = kv
        key = (kv.get("episode"), kv.get("state"))
        if key == (state["episode"], state["state"]):
            # every mass the supervisor takes, a correction too (the record keeps the last)
            mass = (key, kv.get("loaded_mass"))
            if kv.get("state") in ENDED and kv.get("loaded_mass") not in (None, "", "nan") and \
                    state.get("mass_shown") != mass:
                state["mass_shown"] = mass
                print(f"attempt {kv.get('episode')}: weighed {float(kv['loaded_mass']):.2f} kg"
                      f"{' (load cell)' if kv.get('mass_source') == 'load_cell' else ''}, SL "
                      f"{kv.get('success_level', '?')}, success {kv.get('success', '?')}", flush=True)
            return
        state["episode"], state["state"] = key
        s = kv.get("state")
        if s in ENDED:
            state["ended"] += 1
            print(f"attempt {kv.get('episode')} {s}: {kv.get('reason', '')}; {kv.get('elapsed_s', '?')} s, drift front "
                  f"{kv.get('front_drift_pct', '?')} % rear {kv.get('rear_drift_pct', '?')} %, final pitch "
                  f"{kv.get('phi_final_deg', '?')} deg. Weigh the bucket: `m KG` here or `lhd attempt mass KG`",
                  flush=True)
        elif s in ("armed", "running"):
            print(f"attempt {kv.get('episode')} {s} ({kv.get('controller', args.controller)}, slope "
                  f"{kv.get('slope_deg', '?')} deg, {kv.get('material', args.material)})", flush=True)

    def on_diag(msg):
        for st in msg.status:
            if st.name.endswith("supervisor: preflight"):
                state["preflight"] = st
            elif st.name.endswith(": serial link") and state.get("settled"):
                # the bridge's link (a port that does not open, bytes that never make a frame): the
                # checklist only says "no joint states"; printed when its problem changes, and once
                # when it is ok again
                ok = st.level == DiagnosticStatus.OK
                key = "ok" if ok else _NUMBER.sub("#", st.message)
                last = state["link"].get(st.name)
                if key != last and (not ok or last is not None):
                    print(f"serial link: {st.message}", flush=True)
                state["link"][st.name] = key if (not ok or last is not None) else None
            elif st.name.endswith(RECORD_DIAGNOSTICS):
                line = record_diag_line(state["record"], st.name, st.level == DiagnosticStatus.ERROR, st.message)
                if line:
                    print(line, flush=True)
                    state["record_failed"] |= st.level == DiagnosticStatus.ERROR

    children: list[Child] = []
    failed = True
    crashed = ""
    found_at = None
    console = Console(args.interactive if args.interactive is not None else sys.stdin.isatty())
    with _StopOnSignals(stop):
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("lhd_up_real")
        try:
            t_check = time.monotonic() + discovery_wait_s()
            busy = {}
            while not busy and time.monotonic() < t_check and not stop.is_set():
                rclpy.spin_once(node, timeout_sec=0.1)
                busy = {t: n for t in ("/lhd/joint_states", "/lhd/cmd", "/lhd/episode") if (n := node.count_publishers(t))}
            if busy:
                raise RuntimeError(f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')} already has publishers on "
                                   f"{busy}: another LHD bridge, simulator or controller is running there. Stop it, "
                                   "or set ROS_DOMAIN_ID to a free domain")
            node.create_subscription(DiagnosticStatus, "/lhd/episode", on_status, STATUS_QOS)
            node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 50)
            arm = node.create_client(Trigger, "/lhd/arm")
            abort = node.create_client(Trigger, "/lhd/abort")
            pub_mass = node.create_publisher(Float64, "/lhd/attempt/mass", 10)
            for name, module, params, extra in stack(args, run_dir):
                if stop.is_set():
                    break
                children.append(Child(name, module, params, log_dir, quiet, [*ros_args, *extra]))
            print(f"lhd up real: {len(children)} nodes started ({args.controller} controller, port {args.port}); run "
                  f"folder {run_dir}; logs in {log_dir}", flush=True)
            if getattr(args, "actor_note", ""):
                print(f"lhd up real: {args.actor_note}", flush=True)
            t0 = time.monotonic()
            pending = None
            while not stop.is_set():
                rclpy.spin_once(node, timeout_sec=0.05)
                check_children(children, quiet)
                pf = state["preflight"]
                state["settled"] = time.monotonic() - t0 > args.settle
                if pf is not None and state["settled"] and \
                        preflight_key(pf) != state["printed_preflight"]:
                    # the checklist once the nodes settled, and again whenever its problems change
                    # (not their figures: an age or a coordinate changes every second)
                    first = state["printed_preflight"] is None
                    state["printed_preflight"] = preflight_key(pf)
                    print(format_preflight(pf), flush=True)
                    if first and console.enabled:
                        print("keys: Enter = arm | a = abort | m KG = weighed mass | q = quit", flush=True)
                if pending is not None and pending[1].done():
                    what, fut = pending
                    res = fut.result()
                    print(f"{what}: {'ok' if res.success else 'refused'}: {res.message}", flush=True)
                    pending = None
                for line in console.take():
                    if line in ("q", "quit"):
                        stop.set()
                    elif line == "" and pending is None:
                        pending = ("arm", arm.call_async(Trigger.Request()))
                    elif line == "a" and pending is None:
                        pending = ("abort", abort.call_async(Trigger.Request()))
                    elif line.startswith("m "):
                        why = mass_refusal(line[2:].strip(), state["kv"])
                        if why:
                            print(f"`{line}` refused: {why}", flush=True)
                            continue
                        kg = float(line[2:])
                        pub_mass.publish(Float64(data=kg))
                        print(f"attempt {state['kv'].get('episode')}: {kg:g} kg sent to the supervisor", flush=True)
                    else:
                        print(f"`{line}`: keys are Enter (arm), a (abort), m KG (mass), q (quit)", flush=True)
                if args.attempts and state["ended"] >= args.attempts and \
                        time.monotonic() - state.setdefault("t_end", time.monotonic()) > args.linger:
                    break
            failed = False
        except RuntimeError as exc:
            crashed = str(exc).splitlines()[0]           # "<node> exited with status <rc>:"
            found_at = time.time()
            print(f"lhd up real: {exc}\n(node logs in {log_dir})", file=sys.stderr)
            return 1
        finally:
            # the supervisor first: it ends a running attempt (its status stops the controller and the
            # mux) and records it; then the recorder, whose bag then holds that end; then the rest in
            # reverse start order, controller and teleop first, the bridge last (its shutdown sends a
            # stop frame)
            stop_real_stack(children, node)
            if crashed:
                note_crash(run_dir, crashed.rstrip(":"), found_at=found_at)
            if not keep_logs and not failed and args.remove_logs and not state["record_failed"]:
                for f in log_dir.glob("*.log"):         # this run's: an earlier run's, moved aside, stay
                    f.unlink(missing_ok=True)
                import shutil

                shutil.rmtree(log_dir / "rcl", ignore_errors=True)   # rcl's own files (launcher.child_env)
                try:
                    log_dir.rmdir()
                except OSError:
                    pass
    print(f"lhd up real: stopped; attempts in {run_dir / 'attempts.csv'} (`lhd attempts {run_dir}`)", flush=True)
    if state["record_failed"]:
        print(record_failed_message("lhd up real", log_dir, run_dir), file=sys.stderr, flush=True)
        return 1
    return 0


def stop_real_stack(children: list, node) -> None:
    """The supervisor first: it ends a running attempt (its status stops the controller and the
    mux) and records it; then the recorder, whose bag then holds that end; then the rest in reverse
    start order, controller and teleop first, the bridge (and a twin) last (the bridge's shutdown
    sends a stop frame). `lhd up real` and `lhd up twin` alike."""
    first = [c for name in ("supervisor", "recorder") for c in children if c.name == name]
    for c in first:
        c.stop()
    stop_stack([c for c in children if c not in first], node)


# a lost_input end recorded at most this long before the launcher found a node dead is put down
# to that node: a killed controller, mux or bridge is seen by the supervisor as input that stopped
# (after the mux's 0.3 s or its own 0.5 s input timeout) and the launcher, when it is slow (a busy
# computer), can find the dead process after that; 5 s is ten of those timeouts
CRASH_WINDOW_S = 5.0


def note_crash(run_dir: Path, what: str, prog: str = "lhd up real", found_at: float | None = None) -> None:
    """A node process that died ended the stack: the attempt it interrupted was aborted by the
    supervisor's stop ("supervisor stopped during the attempt"), or, when the supervisor itself
    died, left as its row from arming says (INTERRUPTED_REASON); the record says which node it was.
    When the supervisor saw the death first, as input that stopped, the attempt ended as lost_input:
    if that end was recorded (the record file's time) at most CRASH_WINDOW_S before `found_at` (the
    wall time, time.time(), when the launcher found the node dead), the row keeps its outcome and
    its reason names the node as the likely cause."""
    from lhd_loading_ros.task.attempt_record import INTERRUPTED_REASON, csv_path, read_rows, upsert_row

    path = csv_path(run_dir)
    try:
        rows = read_rows(path)
        written = path.stat().st_mtime
    except (OSError, ValueError):
        return
    if not rows:
        return
    from dataclasses import replace

    last = rows[-1]
    if last.outcome == "aborted" and last.reason in ("supervisor stopped during the attempt", INTERRUPTED_REASON):
        tail = ("" if what.startswith("supervisor ") else
                ": the launcher stopped the stack, the supervisor first")
        row = replace(last, reason=f"{what} during the attempt{tail}")
    elif last.outcome == "lost_input" and found_at is not None and what not in last.reason and \
            -0.5 <= found_at - written <= CRASH_WINDOW_S:
        row = replace(last, reason=f"{last.reason}; {what}, found by the launcher {max(found_at - written, 0.0):.1f} s "
                                   "after this end: the likely cause")
    else:
        return
    upsert_row(path, row)
    print(f"{prog}: attempt {row.attempt} recorded as {row.outcome}: {row.reason}", file=sys.stderr, flush=True)


def preflight_problems(st) -> list[str]:
    """The problems of the supervisor's preflight status: its values problem_1..n (a sentence may
    hold "; " itself), or, from a supervisor without them, its message split on "; "."""
    kv = {k.key: k.value for k in st.values}
    listed = [kv[f"problem_{k}"] for k in range(1, 1 + len(kv)) if f"problem_{k}" in kv]
    if listed:
        return listed
    head, _, rest = st.message.partition(": ")
    return rest.split("; ") if rest and head.startswith("not ready") else []


def mass_refusal(text: str, status: dict) -> str:
    """Why the operator's `m KG` cannot weigh the supervisor's latest attempt (its /lhd/episode
    values `status`), or "": the supervisor refuses the same, but only in its log."""
    from lhd_loading_ros.task.attempt_record import check_mass, never_ran_refusal

    try:
        check_mass(text)
    except ValueError as exc:
        return f"{exc} (`m KG`, e.g. `m 23.4`)"
    n, s = status.get("episode", "0"), status.get("state")
    if s not in ENDED:
        return ("no attempt has ended yet" if s in (None, "idle") else f"attempt {n} is {s}") + \
            ": weigh the bucket after the attempt ends"
    if status.get("ran") == "false":
        return never_ran_refusal(n)
    return ""


def format_preflight(st) -> str:
    """The supervisor's preflight status (its `preflight` diagnostics: "ready to arm", or "not
    ready to arm: <problem>; <problem>") as a checklist, one problem per line."""
    problems = preflight_problems(st)
    if not problems:
        return f"preflight: {st.message}"
    return "\n".join(["preflight: not ready to arm"] + [f"  [--] {p}" for p in problems])


_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
def keep_earlier_logs(log_dir: Path) -> Path | None:
    """Node logs an earlier run left in `log_dir` (a run folder reused: the launcher opens each node's log anew)
    moved into log_dir/<UTC time of the newest of them>/, which is returned; None when there were none (a review,
    2026-11-29: yesterday's logs were overwritten)."""
    logs = sorted(log_dir.glob("*.log"))
    if not logs:
        return None
    newest = max(f.stat().st_mtime for f in logs)
    stamp = datetime.fromtimestamp(newest, timezone.utc).strftime("%Y%m%d-%H%M%S")
    dest, k = log_dir / f"earlier_{stamp}", 2
    while dest.exists():
        dest, k = log_dir / f"earlier_{stamp}_{k}", k + 1
    dest.mkdir()
    for f in logs:
        f.rename(dest / f.name)
    return dest


def record_failed_message(prog: str, log_dir, run_dir) -> str:
    """The last line of `lhd up real` / `lhd up twin` when a record or bag error came during the run (exit 1)."""
    return (f"{prog}: the record or a bag could not be written during this run (the record / recorder lines above; "
            f"node logs in {log_dir}): attempts may be missing from {run_dir}")


RECORD_DIAGNOSTICS = ("supervisor: record", "recorder: recording")


def record_diag_line(seen: dict, name: str, error: bool, message: str) -> str | None:
    """The console line for the supervisor's `record` or the recorder's diagnostic, or None: an ERROR when its
    message changes (numbers aside), and once "ok again" after one. A full disk or a removed run folder left the
    console printing "attempt N success" while nothing was kept (a review, 2026-11-29). `seen`: name -> last key."""
    key = _NUMBER.sub("#", message) if error else "ok"
    last = seen.get(name)
    seen[name] = key if (error or last is not None) else None
    if key == last or not (error or last is not None):
        return None
    who = "record" if name.endswith("record") else "recorder"
    return f"{who}: ERROR {message}" if error else f"{who}: ok again: {message}"


def preflight_key(st) -> tuple:
    """What makes the checklist worth printing again: the set of problems with their numbers left
    out (an input's age, the tip's coordinates change every second; the problem does not)."""
    problems = preflight_problems(st)
    return tuple(sorted(_NUMBER.sub("#", p) for p in problems)) if problems else (st.message,)


def parser() -> argparse.ArgumentParser:
    """The options of `lhd up real`; `lhd up twin` parses its stack's options with it too, so the
    twin gets exactly the real stack's defaults."""
    ap = argparse.ArgumentParser(prog="lhd up real", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--port", required=True, help="serial device of the Due, e.g. /dev/ttyACM0")
    ap.add_argument("--controller", choices=CONTROLLERS, default="rld")
    ap.add_argument("--policy", help="exported actor for rld/rlc (default: the machine's, policies/rld_drift_confirm_margin8 or "
                    "rlc_gains, armed on the slopes it was validated on: docs/real_machine.md)")
    ap.add_argument("--camera-topic", default="/camera/image_raw")
    ap.add_argument("--camera-info-topic", default="/camera/camera_info")
    ap.add_argument("--image-reliable", action="store_true", help="subscribe to images reliably (recordings)")
    ap.add_argument("--scan-topic", default="/scan")
    ap.add_argument("--end-zone", default="lidar", help="lidar (from the measured pile) or a surveyed YAML file")
    ap.add_argument("--joy-mapping", default="xbox", help="xbox | ps4 | f710 | a mapping YAML")
    ap.add_argument("--material", choices=["homogeneous", "nonhomogeneous"], default="homogeneous")
    ap.add_argument("--attempt-timeout", type=float, default=10.0, help="s (the paper: 10 s)")
    ap.add_argument("--teleop-attempt-timeout", type=float, default=40.0,
                    help="s, a teleoperated attempt's (--controller teleop; the paper's operators took 10-16 s on average)")
    ap.add_argument("--run-dir", help="attempts.csv and bags go here (default runs/real/<UTC time>)")
    ap.add_argument("--no-record", dest="record", action="store_false", help="no rosbag2 per attempt")
    ap.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap")
    ap.add_argument("--params-file", help="ROS parameter file for every node (default config/real_machine.yaml)")
    ap.add_argument("--config", help="lhd_params.yaml for every node (default: $LHD_CONFIG, else the actor's own where "
                    "it ships one, else the package's)")
    ap.add_argument("--attempts", type=int, default=0, help="stop after N attempts ended (0: until Ctrl-C)")
    ap.add_argument("--linger", type=float, default=2.0, help=argparse.SUPPRESS)
    ap.add_argument("--settle", type=float, default=3.0, help="s before the preflight checklist is printed")
    ap.add_argument("--interactive", dest="interactive", action="store_true", default=None,
                    help="read keys from stdin even if it is not a terminal")
    ap.add_argument("--log-dir", type=Path, help="node logs (default <run-dir>/logs)")
    ap.add_argument("--remove-logs", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--verbose", action="store_true", help="node logs on this terminal")
    return ap


def node_params(params_file: Path | None, node: str) -> dict:
    """The ROS parameters a parameter file gives the node `node` (fully qualified, e.g.
    /lhd_policy), as rcl applies them: every section whose key matches, in file order, a later one
    over an earlier."""
    if params_file is None:
        return {}
    import yaml

    try:
        doc = yaml.safe_load(Path(params_file).read_text()) or {}
    except (OSError, yaml.YAMLError):
        return {}              # the nodes refuse an unreadable file and say why
    return params_of(doc, node)


MIN_COMMANDS_PER_TIMEOUT = 2     # a controller's command may be one period late without the mux timing it out


def command_timing_problem(params_file: Path | None, config: str | None) -> str | None:
    """The controller must publish well within the mux's timeout of its source (`auto`): at
    rate_hz <= 1/timeout every attempt ends as lost_input (the mux drops the source between two
    commands, and a dropped gated source stays cut until the attempt ends), and just above it one
    late command does the same. None when the timing is sound or the files cannot be read (the
    nodes say why then)."""
    from lhd_loading_ros.policy.cmd_mux import MuxConfigError, load_sources
    from lhd_loading_ros.policy.shipped import shipped_config
    from lhd_loading_ros.task.config import ConfigError, load_config

    pol = node_params(params_file, "/lhd_policy")
    mux = node_params(params_file, "/lhd_cmd_mux")
    try:
        if "rate_hz" in pol:
            rate = float(pol["rate_hz"])
            where = f"lhd_policy's rate_hz in {params_file}"
        else:
            rate = float(load_config(config)["paper"]["control"]["frequency_hz"])
            where = f"paper.control.frequency_hz of {config or 'the package config/lhd_params.yaml'}"
        sources_file = mux.get("sources_file") or str(shipped_config("cmd_mux.yaml"))
        auto = [s for s in load_sources(sources_file) if s.topic.strip("/") in ("cmd/auto", "lhd/cmd/auto")]
    except (ConfigError, MuxConfigError, FileNotFoundError, KeyError, TypeError, ValueError):
        return None
    if not auto or not rate > 0:
        return None
    period, timeout = 1.0 / rate, auto[0].timeout
    if MIN_COMMANDS_PER_TIMEOUT * period <= timeout:
        return None
    return (f"the controller's rate {rate:g} Hz ({where}) sends a command every {period:.3g} s, but the "
            f"command mux drops its source '{auto[0].name}' after {timeout:g} s of silence ({sources_file}): "
            f"every attempt would end as lost_input. Expected rate_hz >= {MIN_COMMANDS_PER_TIMEOUT / timeout:.3g} "
            f"(at least {MIN_COMMANDS_PER_TIMEOUT} commands per timeout; the paper's 10 Hz), or a longer timeout "
            "of that source")


PILE_FRAME_PARAMS = (("aruco_pose_node", "frame_id"), ("lidar_slope_node", "frame_id"),
                     ("end_zone_node", "pile_frame_id"), ("lhd_supervisor", "frame_id"))


def pile_frame_problem(params_file: Path | None) -> str | None:
    """The stack's nodes must name the pile frame alike: the end-zone node refuses a slope stamped
    in another frame than its pile_frame_id, so a frame renamed in one node's section only left the
    machine without zones (found at run time, attempt after attempt, as 'no zones')."""
    names = {f"{node}.{param}": str(node_params(params_file, "/" + node).get(param, "pile")) for node, param in
             PILE_FRAME_PARAMS}
    if len({v.strip("/") for v in names.values()}) <= 1:
        return None
    return (f"the pile frame differs between the nodes of {params_file}: "
            + ", ".join(f"{k} = {v!r}" for k, v in names.items())
            + "; expected one name for the pile frame in every node")


def stack_problem(params_file: Path | None, controller: str, config: str | None = None) -> str | None:
    """What in the stack's parameter file would leave every attempt without zones or commands: the
    pile frame named apart (pile_frame_problem), a controller too slow for the mux's timeout
    (command_timing_problem; not for teleop, which has no controller on /lhd/cmd/auto). Run by
    `lhd up real`, `lhd up twin` and real_machine.launch.py before any node starts."""
    return pile_frame_problem(params_file) or (
        command_timing_problem(params_file, config) if controller != "teleop" else None)


def check_args(ap: argparse.ArgumentParser, args) -> None:
    """The checks argparse cannot make (ap.error, exit 2, on a bad value)."""
    from lhd_loading_ros.task.attempt import ATTEMPT_TIMEOUT_RANGE_S

    lo, hi = ATTEMPT_TIMEOUT_RANGE_S
    if not (math.isfinite(args.attempt_timeout) and lo <= args.attempt_timeout <= hi):
        ap.error(f"--attempt-timeout {args.attempt_timeout:g}: expected seconds in [{lo:g}, {hi:g}] (the paper: 10 s, "
                 "to protect the motors)")
    if not (math.isfinite(args.teleop_attempt_timeout) and lo <= args.teleop_attempt_timeout <= hi):
        ap.error(f"--teleop-attempt-timeout {args.teleop_attempt_timeout:g}: expected seconds in [{lo:g}, {hi:g}]")
    if args.attempts < 0:
        ap.error(f"--attempts must be >= 0, got {args.attempts}")
    if args.end_zone != "lidar" and not Path(args.end_zone).is_file():
        ap.error(f"--end-zone {args.end_zone!r}: expected `lidar` or a surveyed YAML file that exists")
    if args.params_file and not Path(args.params_file).is_file():
        ap.error(f"--params-file {args.params_file!r} does not exist")
    if args.policy and args.controller not in ("rld", "rlc"):
        ap.error(f"--policy is the actor's; --controller {args.controller} runs no actor (drop --policy, or use "
                 "--controller rld|rlc)")
    resolve_actor(args)
    params_file = Path(args.params_file) if args.params_file else default_params_file()
    problem = stack_problem(params_file, args.controller, args.config)
    if problem:
        ap.error(problem)
    if args.controller == "teacher":      # its setting refused here as the policy node would refuse it
        from lhd_loading_ros.policy.teacher import TeacherSetting
        from lhd_loading_ros.task.config import ConfigError, load_config

        try:
            TeacherSetting.from_config(load_config(args.config))
        except (ConfigError, ValueError) as exc:
            ap.error(f"--controller teacher: {exc}")
    if args.policy:
        from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy

        from lhd_loading_ros.task.config import ConfigError, load_config

        try:
            pol = load_policy(args.policy)
            pol.check_config(load_config(args.config))   # a bad parameter file: refused before any node starts
        except (PolicyFileError, ConfigError) as exc:
            hint = ""
            if getattr(args, "default_actor", False):
                hint = (f" (--controller {args.controller} runs {args.policy} by default (since 2026-12-02 for rld), with its own "
                        f"parameter file; drop --config / $LHD_CONFIG for it, or name the actor for your file: "
                        f"--policy policies/{args.controller} for the main job's)")
            ap.error(str(exc) + hint)


class MachineActor(NamedTuple):
    policy: str                          # "" for the controllers without an actor
    config: str                          # "" for the nodes' own default
    slope_limits: tuple[float, float] | None    # the supervisor's slope_limits_deg, None for none
    note: str                            # what the console says of the choice ("" when nothing was chosen)


def machine_actor(controller: str, policy: str = "", config: str = "", policies_root=None) -> MachineActor:
    """What the real-machine stack runs for `controller`: for rld / rlc without a policy, the machine's
    actor (actor_file.MACHINE_ACTORS, the ones that pass `lhd eval --stress machine`: placed by hand, from
    rest, on a rough pile), not the main job's, armed only on the slopes where it keeps 0.9 of that case
    (MACHINE_SLOPE_LIMITS_DEG, the supervisor's slope_limits_deg); without a config, an actor that ships its
    own parameter file runs with it (the nodes refuse an actor under another file's observation scaling).
    A config named by --config or $LHD_CONFIG is kept. Other controllers: nothing chosen. `policies_root`:
    where the shipped actors are (default: actor_file.default_policy_dir's). Used by `lhd up real`,
    `lhd up twin`, `lhd bench twin` and real_machine.launch.py."""
    from lhd_loading_ros.policy.actor_file import (MACHINE_ACTORS, MACHINE_SLOPE_LIMITS_DEG, default_policy_dir,
                                                   own_config)

    if controller not in ("rld", "rlc"):
        return MachineActor("", config, None, "")
    note, limits = "", None
    if not policy:
        name = MACHINE_ACTORS[controller]
        policy = str(Path(policies_root) / name if policies_root else default_policy_dir(name))
        limits = MACHINE_SLOPE_LIMITS_DEG[controller]
        note = (f"--controller {controller}: {policy}, the machine's default actor (placed by hand, from rest, on a "
                f"rough pile: docs/real_machine.md), armed on {limits[0]:g}-{limits[1]:g} deg piles; --policy DIR "
                f"runs another")
    own = own_config(policy)
    env = os.environ.get("LHD_CONFIG", "")
    if not config and env:
        note += ("; " if note else "") + f"parameter file {env} ($LHD_CONFIG)"
    elif not config and own is not None:
        config = str(own.resolve())
        note += ("; " if note else "") + f"parameter file {config} (the actor's own)"
    return MachineActor(policy, config, limits, note)


def resolve_actor(args) -> None:
    """machine_actor on the parsed options: sets args.policy, args.config, args.slope_limits and
    args.actor_note (what the console prints)."""
    chosen = machine_actor(args.controller, args.policy or "", args.config or "")
    args.policy = chosen.policy or args.policy
    args.config = chosen.config or args.config
    args.slope_limits, args.actor_note = chosen.slope_limits, chosen.note
    args.default_actor = chosen.slope_limits is not None


def main(argv=None) -> int:
    ap = parser()
    args = ap.parse_args(argv)
    check_args(ap, args)
    if not args.port.strip() or not Path(args.port).exists() or Path(args.port).is_dir():
        # ("" is the current directory to Path, which exists: a review saw nine nodes start for --port "")
        # the bridge would retry a missing port for ever while eight nodes wait: a typo, or the Due
        # not plugged in, is said before anything starts
        ap.error(f"--port {args.port!r} is no serial device (missing, empty or a directory): expected the Due's serial device, e.g. /dev/ttyACM0 "
                 "(`ls /dev/ttyACM* /dev/serial/by-id/`); plug the Due in first")
    return up_real(args)


if __name__ == "__main__":
    raise SystemExit(main())
