"""`lhd echo TOPIC`: print a topic's messages as YAML (for debugging where the ros2 CLI is
absent). The type is discovered from the graph, and the QoS is matched to the publishers the
way `ros2 topic echo` does it: best effort if any publisher is best effort (a reliable reader
would match none of those), transient local if every publisher is (so a latched value sent
before we started still arrives), else reliable and volatile.

Stops cleanly: Ctrl-C, SIGTERM or a closed pipe (`lhd echo T | head -1`) end it with status 0
and no traceback; the signals only set a flag (ros/run.py's run_node).

Only the messages reach stdout; the middleware's own log lines go to stderr (cli/clean_stdout.py)."""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import threading
import time

from lhd_loading_ros.cli.argtypes import nonneg_int
from lhd_loading_ros.cli.clean_stdout import reserve_stdout


class EchoError(Exception):
    """A failure to report on stderr with exit status 1."""


def message_class(type_name: str):
    """'std_msgs/msg/Float64' -> the Python class."""
    try:
        pkg, kind, name = type_name.split("/")
        return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
    except (ValueError, ImportError, AttributeError) as exc:
        raise ValueError(f"cannot import message type {type_name!r}: {exc}") from None


def to_plain(msg):
    """A message as nested dicts / lists / scalars (field order kept)."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {f: to_plain(getattr(msg, f)) for f in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)):
        return [to_plain(v) for v in msg]
    if hasattr(msg, "tolist"):
        return msg.tolist()
    if isinstance(msg, bytes):
        return list(msg)
    return msg


def to_yaml(msg) -> str:
    import yaml

    return yaml.safe_dump(to_plain(msg), sort_keys=False, default_flow_style=False).rstrip()


def matched_qos(publishers, best_effort: bool = False, transient_local: bool = False):
    """The subscription QoS that matches every publisher in `publishers` (TopicEndpointInfo);
    the flags force best effort / transient local."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    qos = QoSProfile(depth=10)
    profiles = [p.qos_profile for p in publishers]
    if best_effort or any(p.reliability == ReliabilityPolicy.BEST_EFFORT for p in profiles):
        qos.reliability = ReliabilityPolicy.BEST_EFFORT
    if transient_local or (profiles and all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles)):
        qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return qos


def _stdout_closed() -> None:
    """The reader went away: point stdout at /dev/null so that Python's final flush does not
    raise again at exit."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd echo", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("topic")
    ap.add_argument("--type", help="message type, e.g. std_msgs/msg/Float64 (default: from the graph)")
    ap.add_argument("--count", type=nonneg_int, default=0, help="exit after N messages (0: until Ctrl-C)")
    ap.add_argument("--wait", type=float, default=10.0, help="seconds to wait for the topic to appear")
    ap.add_argument("--best-effort", action="store_true", help="subscribe best effort whatever the publishers do")
    ap.add_argument("--transient-local", action="store_true",
                    help="subscribe transient local whatever the publishers do")
    args = ap.parse_args(argv)
    # a relative name resolves in the root namespace, as `ros2 topic echo lhd/odom` does (a review)
    args.topic = args.topic if args.topic.startswith("/") else "/" + args.topic
    reserve_stdout()          # before the middleware starts: its log lines go to stderr
    import rclpy

    from lhd_loading_ros.ros.run import SPIN_PERIOD_S, run_node

    stop = threading.Event()
    seen = [0]

    def on_message(msg):
        if stop.is_set():
            return
        try:
            print(to_yaml(msg))
            print("---", flush=True)
        except BrokenPipeError:
            _stdout_closed()
            stop.set()
            return
        seen[0] += 1
        if args.count and seen[0] >= args.count:
            stop.set()

    def make_node():
        node = rclpy.create_node("lhd_echo")
        type_name = args.type
        t_end = time.monotonic() + args.wait
        while not stop.is_set():
            types = dict(node.get_topic_names_and_types())
            if args.topic in types:
                if type_name and type_name not in types[args.topic]:
                    print(f"lhd echo: warning: {args.topic} carries {', '.join(types[args.topic])}, not {type_name}: "
                          "nothing will match; leave --type out to take the graph's", file=sys.stderr, flush=True)
                type_name = type_name or types[args.topic][0]
                break
            if time.monotonic() > t_end:
                if type_name:        # a given type: listen anyway, with the default QoS
                    break
                raise EchoError(f"topic {args.topic} not found after {args.wait:g} s; known topics: "
                                f"{sorted(types) or 'none'}")
            rclpy.spin_once(node, timeout_sec=SPIN_PERIOD_S)
        if type_name:
            try:
                cls = message_class(type_name)
            except (ValueError, ImportError, AttributeError) as exc:
                raise EchoError(f"--type {type_name!r}: expected a message type such as std_msgs/msg/Float64 "
                                f"({exc})") from None
            qos = matched_qos(node.get_publishers_info_by_topic(args.topic), args.best_effort, args.transient_local)
            node.create_subscription(cls, args.topic, on_message, qos)
        return node

    try:
        return run_node(make_node, "lhd echo", args=[], stop=stop)
    except EchoError as exc:
        print(f"lhd echo: {exc}", file=sys.stderr)
        return 1
