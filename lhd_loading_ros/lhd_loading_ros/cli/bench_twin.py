"""`lhd bench twin [--duration S] [--json]`: latency from a camera frame to the command on the
serial line, through the real stack against the digital twin (docs/twin_latency.md).

Starts, as separate processes on real DDS (in the current ROS_DOMAIN_ID, refused when another
LHD stack is there): the twin (lhd_sim_node.twin_node: the simulator as the Due on a pty, the
simulated camera and LiDAR), and the nodes of `lhd up real` with their parameters from
config/real_machine.yaml: bridge, ArUco, LiDAR slope, end zone, supervisor, command mux, and the
RLD actor as the policy node with trigger:=odom on /lhd/cmd/auto (no teleop, no recorder). It arms
attempts one after the other (/lhd/arm) and measures, for every decision the policy makes while
an attempt runs,

    latency = (time the twin's device read the command frame carrying the decision off the pty)
              - (capture time of the camera frame the decision used)

The capture time is the image's header stamp, set by the twin when it renders the machine where
it is (the ArUco node copies it into /lhd/odom, the policy names the odometry stamp it used in its
decision trace <prefix>/policy/decision). The arrival time comes from the twin's
<prefix>/twin/device/commands (every command frame, timed when the device read it). Both are the
system's wall clock, on this one machine.

Matching a decision to its frame: by the wheel set-point, which the frame carries to 1 mrad/s and
which the actor's continuous output changes at nearly every decision: the frame carrying a
decision is the first frame read after the decision was published (CLOCK_MONOTONIC, shared by
all processes) whose set-point is the decision's (clamped to [0, wheels_max] as the bridge does,
and rounded to the wire's 1 mrad/s). A decision whose set-point equals the previous decision's
cannot be told from it on the line and is not counted (`unchanged`); one with no such frame
within 0.5 s is `unmatched` (e.g. overtaken by the mux's own zero at the attempt's end). Decisions
without odometry (stamp 0) or triggered by the fallback timer are reported apart (`fallback`), not
in the latency: the fallback is what runs when the camera does not. With --trigger timer (the
plain 10 Hz timer, for comparison) every timer decision is measured against the stamp of the
odometry it used.

Prints latency_p50_ms, latency_p99_ms, latency_max_ms and n, and the two halves:
camera -> decision published (image, ArUco, DDS, policy) and decision -> serial (mux, bridge's
command period, pty). --json: the last line is one JSON object with the same keys.
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from lhd_loading_ros.task import json_out
from lhd_loading_ros.cli.argtypes import nonneg_int
from lhd_loading_ros.cli.launcher import Child, _StopOnSignals, check_children, stop_stack

WHEEL_SCALE = 1e-3      # rad/s per count of the wheel set-point on the wire (docs/serial_protocol.md)
MATCH_WINDOW_S = 0.5    # s: a decision's frame must be read within this after the decision
ENDED = ("success", "failure", "timeout", "estop", "lost_input", "aborted")


def wheel_key(u_wheels: float, wheels_max: float) -> int:
    """The wheel set-point as the frame carries it: clamped as the bridge's CommandMapper does
    (no reverse, at most wheels_max), in counts of 1 mrad/s."""
    return int(round(min(max(float(u_wheels), 0.0), wheels_max) / WHEEL_SCALE))


def match_decisions(decisions: list[dict], frames: list[tuple], wheels_max: float) -> dict:
    """decisions: dicts with odom_stamp_ns (wall), mono_ns, u_wheels, why ("odom", "fallback",
    ...); frames: (wall_s, mono_s, wheel_setpoint) as the device read them. Returns the latencies
    (ms) of the matched decisions and the counts (module docstring: the method)."""
    decisions = sorted(decisions, key=lambda d: d["mono_ns"])
    frames = sorted(frames, key=lambda f: f[1])
    f_mono = np.array([f[1] for f in frames]) if frames else np.zeros(0)
    f_key = [int(round(f[2] / WHEEL_SCALE)) for f in frames]
    out = {"total": [], "to_decision": [], "to_serial": [], "unchanged": 0, "unmatched": 0, "fallback": 0,
           "decisions": len(decisions), "frames": len(frames)}
    prev = None
    wall_minus_mono = time.time() - time.monotonic()      # the same two clocks in every process here
    for d in decisions:
        key = wheel_key(d["u_wheels"], wheels_max)
        same, prev = key == prev, key
        if d["why"] not in ("odom", "timer") or d["odom_stamp_ns"] <= 0:
            out["fallback"] += 1
            continue
        if same:
            out["unchanged"] += 1
            continue
        t_dec = d["mono_ns"] * 1e-9
        i = int(np.searchsorted(f_mono, t_dec, side="right"))
        hit = None
        while i < len(frames) and f_mono[i] <= t_dec + MATCH_WINDOW_S:
            if f_key[i] == key:
                hit = frames[i]
                break
            i += 1
        if hit is None:
            out["unmatched"] += 1
            continue
        stamp = d["odom_stamp_ns"] * 1e-9
        out["total"].append((hit[0] - stamp) * 1000.0)
        out["to_decision"].append((t_dec + wall_minus_mono - stamp) * 1000.0)
        out["to_serial"].append((hit[1] - t_dec) * 1000.0)
    return out


def summary(m: dict) -> dict:
    def pct(vals, q):
        return float(np.percentile(vals, q)) if vals else math.nan

    return {"latency_p50_ms": pct(m["total"], 50), "latency_p99_ms": pct(m["total"], 99),
            "latency_max_ms": float(max(m["total"])) if m["total"] else math.nan, "n": len(m["total"]),
            "camera_to_decision_p50_ms": pct(m["to_decision"], 50),
            "camera_to_decision_p99_ms": pct(m["to_decision"], 99),
            "decision_to_serial_p50_ms": pct(m["to_serial"], 50),
            "decision_to_serial_p99_ms": pct(m["to_serial"], 99),
            "decisions": m["decisions"], "unchanged": m["unchanged"], "unmatched": m["unmatched"],
            "fallback": m["fallback"], "command_frames": m["frames"]}


def default_params_file() -> Path | None:
    from lhd_loading_ros.cli.up_real import default_params_file as f

    return f()


def stack(args, run_dir: Path, link: str, params_file: Path | None) -> list[tuple[str, str, dict, list[str]]]:
    common = {"config": args.config} if args.config else {}
    policy_dir = str(Path(args.policy).resolve())      # main() resolves it: the machine's actor by default
    return [
        ("twin", "lhd_sim_node.twin_node",
         {**common, "link": link, "machine_params": str(params_file or ""), "slopes_deg": args.slopes,
          "seed": args.seed, "camera_fps": args.camera_fps, "reset_delay": args.reset_delay,
          "markers_hz": 0.0, **({"imu_hz": args.imu_hz} if args.imu_hz > 0 else {})}, []),
        ("bridge", "lhd_hw_bridge.bridge_node", {**common, "port": link}, []),
        ("aruco", "lhd_loading_ros.nodes.aruco_pose_node",
         {"image_topic": "/camera/image_raw", "camera_info_topic": "/camera/camera_info"}, []),
        ("lidar", "lhd_loading_ros.nodes.lidar_slope_node", {"scan_topic": "/scan"}, []),
        ("end_zone", "lhd_loading_ros.nodes.end_zone_node", {**common, "source": "lidar"}, []),
        ("supervisor", "lhd_loading_ros.nodes.supervisor_node",
         {**common, "run_dir": str(run_dir), "controller": "rld", "policy_dir": policy_dir,
          "attempt_timeout": args.attempt_timeout}, []),
        ("mux", "lhd_loading_ros.nodes.cmd_mux_node", {**common}, []),
        ("controller", "lhd_loading_ros.nodes.policy_node",
         {**common, "policy_dir": policy_dir, "trigger": args.trigger, "cmd_topic": "cmd/auto"}, []),
    ]


def run_bench(args) -> dict:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import Float64MultiArray
    from std_srvs.srv import Trigger

    from lhd_loading_ros.ros.params import discovery_wait_s
    from lhd_loading_ros.ros.qos import MEASUREMENT_QOS, STATUS_QOS
    from lhd_loading_ros.task.config import load_config

    cfg = load_config(args.config or None)
    wheels_max = float(cfg["paper"]["control"]["wheels_max"])
    work = Path(tempfile.mkdtemp(prefix="lhd_bench_twin_"))
    log_dir = Path(args.log_dir) if args.log_dir else work / "logs"
    log_dir.mkdir(parents=True, exist_ok=True)
    link = str(work / "due")
    params_file = Path(args.params_file) if args.params_file else default_params_file()
    ros_args = ["--params-file", str(params_file)] if params_file else []
    decisions: list[dict] = []
    frames: list[tuple] = []
    st = {"state": None, "episode": None, "running_since": None, "running_s": 0.0, "attempts": 0, "ended": []}

    def on_decision(msg):
        kv = {k.key: k.value for k in msg.values}
        if st["state"] != "running":
            return
        try:
            decisions.append({"odom_stamp_ns": int(kv["odom_stamp_ns"]), "mono_ns": int(kv["mono_ns"]),
                              "u_wheels": float(kv["command"].split(",")[0]), "why": msg.message,
                              "reason": kv.get("reason", "")})
        except (KeyError, ValueError):
            pass

    def on_frames(msg):
        d = list(msg.data)
        for i in range(0, len(d) - 5, 6):
            frames.append((d[i], d[i + 1], d[i + 2]))

    def on_status(msg):
        kv = {k.key: k.value for k in msg.values}
        s, ep = kv.get("state", msg.message), kv.get("episode")
        now = time.monotonic()
        if st["state"] == "running" and s != "running" and st["running_since"] is not None:
            st["running_s"] += now - st["running_since"]
            st["running_since"] = None
        if s == "running" and st["state"] != "running":
            st["running_since"] = now
            st["attempts"] += 1
        if s in ENDED and (s, ep) not in st["ended"]:
            st["ended"].append((s, ep))
        st["state"], st["episode"] = s, ep

    def running_s():
        return st["running_s"] + (time.monotonic() - st["running_since"] if st["running_since"] else 0.0)

    stop = threading.Event()
    children: list[Child] = []
    quiet = not args.verbose
    error = None
    with _StopOnSignals(stop):
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("lhd_bench_twin")
        try:
            t_check = time.monotonic() + discovery_wait_s()
            busy = {}
            while not busy and time.monotonic() < t_check:
                rclpy.spin_once(node, timeout_sec=0.1)
                busy = {t: n for t in ("/lhd/joint_states", "/lhd/cmd", "/lhd/episode") if (n := node.count_publishers(t))}
            if busy:
                raise RuntimeError(f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')} already has publishers on "
                                   f"{busy}: another LHD stack is running there; set ROS_DOMAIN_ID to a free domain")
            node.create_subscription(DiagnosticStatus, "/lhd/policy/decision", on_decision, MEASUREMENT_QOS)
            node.create_subscription(Float64MultiArray, "/lhd/twin/device/commands", on_frames, MEASUREMENT_QOS)
            node.create_subscription(DiagnosticStatus, "/lhd/episode", on_status, STATUS_QOS)
            arm = node.create_client(Trigger, "/lhd/arm")
            for name, module, params, extra in stack(args, work / "run", link, params_file):
                children.append(Child(name, module, params, log_dir, quiet, [*ros_args, *extra]))
            t_start = time.monotonic()
            deadline = t_start + args.timeout
            pending, next_try = None, 0.0
            refusals = []
            while not stop.is_set() and running_s() < args.duration:
                rclpy.spin_once(node, timeout_sec=0.02)
                now = time.monotonic()
                if now > deadline:
                    raise RuntimeError(f"only {running_s():.1f} s of attempts in {args.timeout:g} s (wanted "
                                       f"{args.duration:g} s); last arming refusals: {refusals[-3:]}")
                check_children(children)
                if pending is not None and pending.done():
                    res = pending.result()
                    if not res.success:
                        refusals.append(res.message)
                    pending = None
                if pending is None and now >= next_try and arm.service_is_ready() and \
                        st["state"] in ("idle", *ENDED) and st["state"] is not None:
                    pending = arm.call_async(Trigger.Request())
                    next_try = now + 0.5
            t_end = time.monotonic() + 0.5          # the last frames' trace
            while time.monotonic() < t_end:
                rclpy.spin_once(node, timeout_sec=0.02)
        except RuntimeError as exc:
            error = str(exc)
        finally:
            stop_stack(children, node)
    if error:
        raise RuntimeError(f"{error}\n(node logs in {log_dir})")
    result = summary(match_decisions(decisions, frames, wheels_max))
    result.update(trigger=args.trigger, attempts=st["attempts"], running_s=round(running_s(), 2),
                  ended=[s for s, _ in st["ended"]], camera_fps=args.camera_fps, imu_hz=args.imu_hz)
    if not args.log_dir and not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd bench twin", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=30.0, help="s of running attempts to measure (default 30)")
    ap.add_argument("--timeout", type=float, default=0.0, help="s of wall time before giving up "
                    "(default: 60 + 3 x duration)")
    ap.add_argument("--slopes", default="20", help="pile slopes, degrees, cycled per attempt (default 20)")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--trigger", choices=("odom", "timer"), default="odom",
                    help="the policy node's trigger (timer: the 10 Hz steady timer, for comparison)")
    ap.add_argument("--camera-fps", type=float, default=30.0, help="the simulated camera's frame rate")
    imu = ap.add_mutually_exclusive_group()
    from lhd_loading_ros.cli.up_twin import TWIN_IMU_HZ

    imu.add_argument("--imu", dest="imu_hz", type=float, nargs="?", const=TWIN_IMU_HZ, default=TWIN_IMU_HZ, metavar="HZ",
                    help="the default: the twin's machine has an IMU on its rear frame (/lhd/imu at HZ, 50 by default, "
                         "as in `lhd up twin`): the ArUco node places the machine with its tilt and integrates its "
                         "acceleration, holding each image's odometry back for the sample that covers it "
                         "(imu_accel_wait)")
    imu.add_argument("--no-imu", dest="imu_hz", action="store_const", const=0.0,
                    help="the paper's machine, without an IMU (`lhd up twin --no-imu`)")
    ap.add_argument("--attempt-timeout", type=float, default=10.0, help="s, the supervisor's (the paper: 10)")
    ap.add_argument("--reset-delay", type=float, default=1.5, help="s from an ended attempt to the twin's new pile")
    ap.add_argument("--policy", help="exported actor (default: the machine's RLD, policies/rld_drift_confirm_margin8, as lhd up real)")
    ap.add_argument("--params-file", help="ROS parameter file for every node (default config/real_machine.yaml)")
    ap.add_argument("--config", help="lhd_params.yaml (default: as lhd up real: $LHD_CONFIG, else the actor's own, "
                    "else the package's)")
    ap.add_argument("--log-dir", help="node logs here (kept); default: a temporary folder, removed")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder (logs, attempts)")
    ap.add_argument("--verbose", action="store_true", help="node logs on this terminal")
    ap.add_argument("--json", action="store_true", help="last line: the figures as one JSON object")
    args = ap.parse_args(argv)
    if args.json:             # the JSON line alone on stdout (cli/clean_stdout.py)
        from lhd_loading_ros.cli.clean_stdout import reserve_stdout

        reserve_stdout()
    if not (math.isfinite(args.duration) and args.duration > 0):
        ap.error(f"--duration must be a positive number of seconds, got {args.duration}")
    if args.timeout and not (math.isfinite(args.timeout) and args.timeout > 0):
        ap.error(f"--timeout must be a positive number of seconds (0: the default), got {args.timeout}")
    if args.camera_fps <= 0:
        ap.error(f"--camera-fps must be positive, got {args.camera_fps}")
    from lhd_loading_ros.cli.up_real import machine_actor
    from lhd_loading_ros.cli.up_twin import slope_range_problem
    from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy
    from lhd_loading_ros.task.config import ConfigError, load_config

    # the actor and the file the machine runs (cli/up_real.machine_actor), so the latency is the machine's
    chosen = machine_actor("rld", args.policy or "", args.config or "")
    args.policy, args.config = chosen.policy, chosen.config or args.config
    try:
        load_policy(args.policy).check_config(load_config(args.config or None))
    except (PolicyFileError, ConfigError) as exc:
        ap.error(str(exc))
    try:
        slopes = [float(v) for v in str(args.slopes).replace(",", " ").split()]
    except ValueError:
        slopes = []
    if not slopes:
        ap.error(f"--slopes {args.slopes!r}: expected degrees, e.g. 20 or '15,30'")
    bad = slope_range_problem(slopes, args.config)
    if bad:
        ap.error(bad)
    args.slopes = ",".join(f"{v:g}" for v in slopes)
    if not (args.imu_hz == 0.0 or 1.0 <= args.imu_hz <= 200.0):
        ap.error(f"--imu {args.imu_hz:g}: expected an IMU rate in [1, 200] Hz (the twin's imu_hz; --no-imu: none)")
    if args.params_file and not Path(args.params_file).is_file():
        ap.error(f"--params-file {args.params_file!r} does not exist")
    args.timeout = args.timeout or 60.0 + 3.0 * args.duration
    try:
        r = run_bench(args)
    except RuntimeError as exc:
        print(f"lhd bench twin: {exc}", file=sys.stderr)
        return 1
    print(f"lhd bench twin: camera frame -> command frame on the serial line, {r['n']} decisions of "
          f"{r['attempts']} attempt(s), {r['running_s']:g} s running (camera {args.camera_fps:g} fps, "
          f"policy trigger {args.trigger}{f', IMU {args.imu_hz:g} Hz' if args.imu_hz else ', no IMU'})")
    print(f"  latency   p50 {r['latency_p50_ms']:.1f} ms   p99 {r['latency_p99_ms']:.1f} ms   max "
          f"{r['latency_max_ms']:.1f} ms   (target p99 <= 60 ms)")
    print(f"  camera -> decision  p50 {r['camera_to_decision_p50_ms']:.1f} ms  p99 "
          f"{r['camera_to_decision_p99_ms']:.1f} ms;  decision -> serial  p50 {r['decision_to_serial_p50_ms']:.1f} ms"
          f"  p99 {r['decision_to_serial_p99_ms']:.1f} ms")
    print(f"  decisions {r['decisions']}: matched {r['n']}, same set-point as the previous {r['unchanged']}, "
          f"unmatched {r['unmatched']}, fallback/no odometry {r['fallback']}; {r['command_frames']} command frames")
    if args.json:
        print(json_out.dumps(r))
    if r["n"] == 0:
        print("lhd bench twin: no decision could be matched to a command frame", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
