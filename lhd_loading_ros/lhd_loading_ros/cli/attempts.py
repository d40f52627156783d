"""The attempt commands of `lhd` (docs/supervisor.md):

  lhd attempts RUN_DIR [--json]               the paper's results table from RUN_DIR/attempts.csv
  lhd attempt mass KG [--attempt N] [--run-dir DIR]
                                              the weighed mass of the latest ended attempt (or of
                                              attempt N), through the supervisor; --run-dir edits
                                              the record directly when no supervisor runs
  lhd arm                                     preflight + arm (the supervisor's Trigger service)
  lhd abort                                   abort the live attempt

Exit status: 0 done; 1 refused (with the reason), no supervisor answering, or no record;
2 a bad argument (a mass that is NaN, negative or over 200 kg).
Also `python -m lhd_loading_ros.cli.attempts attempts|mass|arm|abort ...`."""
from __future__ import annotations

import argparse
import math
import sys
import time

from lhd_loading_ros.task import json_out
from lhd_loading_ros.cli.argtypes import pos_float, pos_int, topic_prefix
from lhd_loading_ros.task.attempt import ENDED
from lhd_loading_ros.task.attempt_record import (NEEDS_MASS, CSV_NAME, check_mass, csv_path, format_table, read_rows,
                                                 never_ran_refusal, summarize, weigh_row)

WAIT_S = 5.0
HISTORY_S = 0.3          # s to let a latched topic's history arrive after its first message


def _stamp(status: dict) -> int:
    try:
        return int(status.get("stamp_ns", "0"))
    except ValueError:
        return 0


def _newest(statuses: list) -> dict:
    """The newest of the statuses heard: the largest stamp, and of equal stamps the last to arrive (a
    supervisor on sim time without /clock stamps every status 0; the latched history comes in order)."""
    return max(enumerate(statuses), key=lambda e: (_stamp(e[1]), e[0]))[1]


def _unweighed_hint(run_dir: str) -> str:
    """Where the run's record has ended attempts still without a mass (a supervisor restarted on the same
    run directory starts idle and weighs only what it runs itself): the command that weighs the latest."""
    try:
        rows = [r for r in read_rows(csv_path(run_dir)) if r.mass_kg is None and r.outcome in NEEDS_MASS]
    except (OSError, ValueError):
        return ""
    if not rows:
        return ""
    n = rows[-1].attempt
    return (f"; the record {csv_path(run_dir)} has attempt {n} (from before this supervisor started) still "
            f"unweighed: `lhd attempt mass KG --attempt {n}` records it")


def _err(prog: str, msg: str, rc: int = 1) -> int:
    print(f"{prog}: {msg}", file=sys.stderr)
    return rc


# ------------------------------------------------------------------ lhd attempts
def main(argv=None) -> int:
    """`lhd attempts RUN_DIR [--json]`."""
    ap = argparse.ArgumentParser(prog="lhd attempts", description="the paper's results table from a run's "
                                 f"{CSV_NAME} (per controller x material x slope rounded to 5 deg)")
    ap.add_argument("run_dir", help=f"run folder (the supervisor's run_dir) or its {CSV_NAME}")
    ap.add_argument("--json", action="store_true", help="the table as JSON")
    args = ap.parse_args(argv)
    path = csv_path(args.run_dir)
    if not path.is_file():
        return _err("lhd attempts", f"no {CSV_NAME} at {path}: is {args.run_dir} a supervisor's run_dir?")
    try:
        rows = read_rows(path)
    except ValueError as exc:
        return _err("lhd attempts", str(exc))
    summary = summarize(rows)
    if args.json:
        print(json_out.dumps({"csv": str(path), **summary}, indent=2))
    else:
        print(format_table(summary, title=f"Attempts in {path}"))
    return 0


# ------------------------------------------------------------------ ROS helpers
def _ros_args(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--namespace", type=topic_prefix, default="/lhd", help="the machine's topic prefix (default /lhd)")
    ap.add_argument("--timeout", type=pos_float, default=WAIT_S, help=f"seconds to wait for the supervisor "
                    f"(default {WAIT_S:g})")


class _Ros:
    """rclpy for one short command: init without signal handlers (Ctrl-C: KeyboardInterrupt,
    caught by the callers), one node, shutdown on exit."""

    def __init__(self, name: str):
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        self.rclpy = rclpy
        rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name)

    def spin_until(self, pred, timeout: float) -> bool:
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            if pred():
                return True
            self.rclpy.spin_once(self.node, timeout_sec=0.02)
        return pred()

    def close(self) -> None:
        self.node.destroy_node()
        if self.rclpy.ok():
            self.rclpy.shutdown()


def _trigger(what: str, argv) -> int:
    prog = f"lhd {what}"
    ap = argparse.ArgumentParser(prog=prog, description={"arm": "preflight check, then arm the next attempt",
                                                         "abort": "abort the attempt in progress"}[what])
    _ros_args(ap)
    args = ap.parse_args(argv)
    service = f"{args.namespace.rstrip('/')}/{what}"
    ros = None
    try:
        from std_srvs.srv import Trigger

        ros = _Ros(f"lhd_{what}")
        client = ros.node.create_client(Trigger, service)
        if not client.wait_for_service(timeout_sec=args.timeout):
            return _err(prog, f"no supervisor: service {service} not available after {args.timeout:g} s "
                              "(is the supervisor node running, in this ROS_DOMAIN_ID?)")
        fut = client.call_async(Trigger.Request())
        if not ros.spin_until(fut.done, args.timeout):
            return _err(prog, f"{service} did not answer within {args.timeout:g} s")
        res = fut.result()
        print(res.message)
        return 0 if res.success else 1
    except KeyboardInterrupt:
        return 130
    finally:
        if ros is not None:
            ros.close()


def arm_main(argv=None) -> int:
    """`lhd arm [--namespace NS] [--timeout S]`: prints the supervisor's answer; 1 when refused."""
    return _trigger("arm", argv)


def abort_main(argv=None) -> int:
    """`lhd abort [--namespace NS] [--timeout S]`."""
    return _trigger("abort", argv)


# ------------------------------------------------------------------ lhd attempt mass
def _print_row(row) -> None:
    d = row.to_csv()
    print("  ".join(f"{k}={v}" for k, v in d.items() if k in ("attempt", "controller", "slope_deg", "material",
                                                                 "outcome", "mass_kg", "elapsed_s", "phi_final_deg",
                                                                 "success_level", "success")))


def _phi_thresh(config: str | None) -> float:
    """The success test's pitch threshold (rad) of a parameter file (default: the default file):
    only for rows recorded before the record kept the supervisor's own (phi_thresh_deg)."""
    from lhd_loading_ros.task.config import load_config
    from lhd_loading_ros.task.params import TaskParams

    return TaskParams.from_config(load_config(config)).phi_thresh_pitch


def attempt_mass_main(argv=None) -> int:
    """`lhd attempt mass KG [--attempt N] [--run-dir DIR] [--namespace NS] [--timeout S]`."""
    prog = "lhd attempt mass"
    ap = argparse.ArgumentParser(prog=prog, description="the weighed mass (kg) of the latest ended attempt "
                                 "(or of attempt N), recorded by the supervisor")
    ap.add_argument("kg", help="the bucket's load on the scale, kg (0-200)")
    ap.add_argument("--attempt", type=pos_int, help="attempt number (default: the latest ended one)")
    ap.add_argument("--run-dir", help="edit this run's record directly, without a supervisor")
    ap.add_argument("--config", help="for a row recorded without its pitch threshold (before 2026-11-30), weighed "
                    "from the record (--run-dir, or --attempt N of an earlier attempt): the supervisor's parameter "
                    "file (default: the default one)")
    _ros_args(ap)
    args = ap.parse_args(argv)
    try:
        kg = check_mass(args.kg)
    except ValueError as exc:
        return _err(prog, f"refused: {exc}", 2)
    if args.config and not args.run_dir and args.attempt is None:
        return _err(prog, "refused: --config is for a weighing of the record (--run-dir, or --attempt N of an earlier "
                          "attempt); a running supervisor judges its latest attempt with its own file", 2)
    if args.run_dir:
        return _weigh_offline(prog, csv_path(args.run_dir), args.attempt, kg, args.config)
    ros = None
    try:
        from diagnostic_msgs.msg import DiagnosticStatus
        from std_msgs.msg import Float64

        from lhd_loading_ros.ros.qos import STATUS_QOS
        from lhd_loading_ros.nodes.supervisor_node import MASS_QOS

        ns = args.namespace.rstrip("/")
        ros = _Ros("lhd_attempt_mass")
        latest: list[dict] = []
        ros.node.create_subscription(DiagnosticStatus, f"{ns}/episode",
                                     lambda m: latest.append({k.key: k.value for k in m.values}), STATUS_QOS)
        if not ros.spin_until(lambda: latest, args.timeout):
            return _err(prog, f"no supervisor: nothing on {ns}/episode after {args.timeout:g} s (or use --run-dir)")
        ros.spin_until(lambda: False, HISTORY_S)      # the latched history comes in a burst: take the newest
        st = _newest(latest)
        if "controller" not in st or "run_dir" not in st:
            return _err(prog, f"{ns}/episode comes from the simulator, not a supervisor: nothing to weigh")
        n = st.get("episode", "0")
        if args.attempt is not None and str(args.attempt) != n:
            # an earlier attempt: the supervisor weighs its latest only; the record is edited directly
            return _weigh_offline(prog, csv_path(st["run_dir"]), args.attempt, kg, args.config)
        if args.config:
            return _err(prog, f"refused: --config with attempt {n}, the supervisor's latest: it judges it with its own "
                              "file", 2)
        if st.get("state") not in ENDED:
            what = "no attempt has ended yet" if st.get("state") == "idle" else f"attempt {n} is {st.get('state')}"
            hint = _unweighed_hint(st["run_dir"]) if st.get("state") == "idle" else ""
            return _err(prog, f"refused: {what}; weigh the bucket after the attempt ends{hint}")
        if st.get("ran") == "false":
            return _err(prog, f"refused: {never_ran_refusal(n)}")
        pub = ros.node.create_publisher(Float64, f"{ns}/attempt/mass", MASS_QOS)
        if not ros.spin_until(lambda: pub.get_subscription_count() > 0, args.timeout):
            return _err(prog, f"no supervisor subscribes {ns}/attempt/mass")
        pub.publish(Float64(data=kg))

        def confirmed() -> bool:
            s = _newest(latest)
            try:
                return s.get("episode") == n and abs(float(s.get("loaded_mass", "nan")) - kg) < 0.006
            except ValueError:
                return False

        if not ros.spin_until(confirmed, args.timeout):
            return _err(prog, f"the supervisor did not confirm {kg:g} kg for attempt {n} within {args.timeout:g} s "
                              "(see its log)")
        s = _newest(latest)
        row = None
        try:
            row = next((r for r in read_rows(csv_path(s.get("run_dir", ""))) if str(r.attempt) == n), None)
        except (OSError, ValueError):
            pass
        if row is not None:
            _print_row(row)
        else:   # the record is on another machine: what the supervisor says
            print("  ".join(f"{k}={s.get(k, '')}" for k in ("episode", "controller", "slope_deg", "material", "state",
                                                             "loaded_mass", "elapsed_s", "phi_final_deg",
                                                             "success_level", "success")))
        return 0
    except KeyboardInterrupt:
        return 130
    finally:
        if ros is not None:
            ros.close()


def _weigh_offline(prog: str, path, attempt, kg: float, config: str | None = None) -> int:
    from lhd_loading_ros.task.config import ConfigError, config_hash, load_config

    try:
        before = {r.attempt: r for r in read_rows(path)}
        fallback = cfg = None
        # a row recorded with its supervisor's pitch threshold is judged on it (a review, 2026-11-29: offline
        # weighing judged every row on the default file's threshold, whatever file the supervisor ran);
        # an older row on --config's, or the default file's, said
        old_rows = [r for r in before.values() if not math.isfinite(r.phi_thresh_deg)]
        if old_rows:
            cfg = load_config(config)
            fallback = _phi_thresh(config)
        row = weigh_row(path, attempt, kg, fallback)
    except ConfigError as exc:
        return _err(prog, f"--config: {exc}", 2)
    except (OSError, ValueError) as exc:
        return _err(prog, str(exc))
    _print_row(row)
    old = before.get(row.attempt)
    if old is not None and not math.isfinite(old.phi_thresh_deg):
        src = config or "the default parameter file"
        print(f"attempt {row.attempt}: recorded without its pitch threshold; judged on {src}'s "
              f"{math.degrees(fallback):g} deg", flush=True)
        if old.config_hash and old.config_hash != config_hash(cfg):
            print(f"warning: attempt {row.attempt} was judged by a supervisor running a parameter file with hash "
                  f"{old.config_hash}, not {src} ({config_hash(cfg)}): pass its file with --config", file=sys.stderr,
                  flush=True)
    # what the weighing changed besides, said (a review, 2026-11-29: an earlier mass was replaced and an attempt
    # still waiting for its mass went unmentioned)
    old = before.get(row.attempt)
    if old is not None and old.mass_kg is not None and abs(old.mass_kg - row.mass_kg) >= 0.005:
        print(f"attempt {row.attempt}: {old.mass_kg:.2f} kg replaced by {row.mass_kg:.2f} kg", flush=True)
    waiting = sorted(n for n, r in before.items() if n != row.attempt and r.mass_kg is None and r.outcome in NEEDS_MASS)
    if waiting:
        print(f"still unweighed: attempt(s) {', '.join(map(str, waiting))} (`lhd attempt mass KG --attempt N`)",
              flush=True)
    return 0


COMMANDS = {"attempts": main, "mass": attempt_mass_main, "arm": arm_main, "abort": abort_main}


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] not in COMMANDS:
        print(__doc__)
        raise SystemExit(2)
    raise SystemExit(COMMANDS[sys.argv[1]](sys.argv[2:]))
