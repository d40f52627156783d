"""`lhd echo TOPIC`: print a topic's messages as YAML (for debugging where the ros2 CLI is
absent). The type is discovered from the graph; QoS: reliable, or --best-effort."""
from __future__ import annotations

import argparse
import importlib
import sys
import time


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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd echo", description=__doc__)
    ap.add_argument("topic")
    ap.add_argument("--type", help="message type, e.g. std_msgs/msg/Float64 (default: from the graph)")
    ap.add_argument("--count", type=int, default=0, help="exit after N messages (0: until Ctrl-C)")
    ap.add_argument("--wait", type=float, default=10.0, help="seconds to wait for the topic to appear")
    ap.add_argument("--best-effort", action="store_true", help="subscribe best effort (sensor data)")
    ap.add_argument("--transient-local", action="store_true", help="also get the last messages of latched topics")
    args = ap.parse_args(argv)
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    rclpy.init()
    node = rclpy.create_node("lhd_echo")
    try:
        type_name = args.type
        t_end = time.monotonic() + args.wait
        while type_name is None:
            types = dict(node.get_topic_names_and_types())
            if args.topic in types:
                type_name = types[args.topic][0]
                break
            if time.monotonic() > t_end:
                print(f"lhd echo: topic {args.topic} not found after {args.wait:g} s; known topics: "
                      f"{sorted(types) or 'none'}", file=sys.stderr)
                return 1
            rclpy.spin_once(node, timeout_sec=0.1)
        try:
            cls = message_class(type_name)
        except ValueError as exc:
            print(f"lhd echo: {exc}", file=sys.stderr)
            return 1
        qos = QoSProfile(depth=10)
        qos.reliability = ReliabilityPolicy.BEST_EFFORT if args.best_effort else ReliabilityPolicy.RELIABLE
        if args.transient_local:
            qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
        seen = [0]

        def cb(msg):
            print(to_yaml(msg))
            print("---", flush=True)
            seen[0] += 1

        node.create_subscription(cls, args.topic, cb, qos)
        while rclpy.ok() and (args.count == 0 or seen[0] < args.count):
            rclpy.spin_once(node, timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
