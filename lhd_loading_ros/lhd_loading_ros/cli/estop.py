"""`lhd estop on|off|status`: the software e-stop of the command mux (docs/teleop.md).

  on      publish <prefix>/estop true (latched) and wait until the command mux reports
          `estop` on <prefix>/cmd_mux/active: every command source is blocked, zeros go out
  off     publish false and wait until the mux no longer reports `estop`; sources resume only
          once they have been silent for their timeout (the operator presses the deadman anew)
  status  print the e-stop value(s) published and the mux's selection

Exit status: 0 confirmed (status: the mux answered), 1 no confirmation within --timeout (is
lhd_cmd_mux running, on this ROS_DOMAIN_ID?), 2 usage. This is the software lock of the
command chain; the machine's own emergency-stop button acts in the device itself.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

from lhd_loading_ros.cli.argtypes import pos_float, topic_prefix


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd estop", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("action", choices=("on", "off", "status"))
    ap.add_argument("--namespace", type=topic_prefix, default="/lhd", help="topic prefix of the machine (default /lhd)")
    # 10 s: it returns as soon as the mux confirms; only a missing mux waits it out. 3 s (until
    # 2026-11-28) was sometimes shorter than a new process's DDS discovery on a loaded 2-core
    # machine, and a safety command must not report "no confirmation" for a mux that is there
    ap.add_argument("--timeout", type=pos_float, default=10.0,
                    help="seconds to wait for the mux (default 10; it returns as soon as the mux confirms); "
                         "status listens at least 1 s")
    args = ap.parse_args(argv)
    ns = args.namespace           # checked by topic_prefix: "/name", a ROS namespace

    import rclpy
    from rclpy.duration import Duration
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import Bool, String

    from lhd_loading_ros.ros.qos import LATCHED_QOS

    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("lhd_estop", start_parameter_services=False)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    heard = {"active": None, "estop": []}
    try:
        # latched (LATCHED_QOS): the mux's current selection and every latched e-stop value
        node.create_subscription(String, f"{ns}/cmd_mux/active", lambda m: heard.__setitem__("active", m.data),
                                 LATCHED_QOS)
        node.create_subscription(Bool, f"{ns}/estop", lambda m: heard["estop"].append(bool(m.data)), LATCHED_QOS)
        want = None
        if args.action in ("on", "off"):
            engage = args.action == "on"
            # latched, so a mux that discovers us late (or restarts meanwhile) still receives it
            pub = node.create_publisher(Bool, f"{ns}/estop", LATCHED_QOS)
            pub.publish(Bool(data=engage))
            want = (lambda a: a == "estop") if engage else (lambda a: a is not None and a != "estop")
        t_end = time.monotonic() + args.timeout
        while time.monotonic() < t_end:
            ex.spin_once(timeout_sec=0.05)
            if want is not None and heard["active"] is not None and want(heard["active"]):
                break
            if (want is None and heard["active"] is not None and time.monotonic() > t_end - args.timeout + 1.0
                    and len(heard["estop"]) >= node.count_publishers(f"{ns}/estop")):
                break           # status: the mux answered, and every latched e-stop publisher
        active = heard["active"]
        domain = os.environ.get("ROS_DOMAIN_ID", "0")
        if want is not None:
            # before our latched value goes away with us: every subscriber the graph knows of
            # (teleop nodes mirror it, a supervisor obeys it) has matched and acknowledged it
            t_ack = max(t_end, time.monotonic() + 0.5)
            while time.monotonic() < t_ack and pub.get_subscription_count() < node.count_subscribers(f"{ns}/estop"):
                ex.spin_once(timeout_sec=0.02)
            pub.wait_for_all_acked(Duration(seconds=1.0))
            if active is not None and want(active):
                print(f"e-stop {'ENGAGED' if args.action == 'on' else 'released'} on {ns}/estop: lhd_cmd_mux confirms "
                      f"(active: {active})")
                return 0
            print(f"lhd estop: {ns}/estop set to {args.action == 'on'}, but no confirmation from the command mux "
                  f"within {args.timeout:g} s ({ns}/cmd_mux/active is {active!r}): is lhd_cmd_mux running on "
                  f"ROS_DOMAIN_ID={domain}?" + (" The e-stop may NOT be in effect." if args.action == "on" else ""),
                  file=sys.stderr)
            return 1
        values = sorted(set(heard["estop"]))
        est = "no latched publisher now (a running mux keeps the last value it heard)" if not values else ("ENGAGED" if values == [True] else
                                                 "released" if values == [False] else
                                                 "latched publishers disagree (true and false); the mux's state below is "
                                                 "what counts")
        print(f"{ns}/estop: {est}")
        print(f"{ns}/cmd_mux/active: {active if active is not None else 'no command mux heard'}")
        return 0 if active is not None else 1
    except KeyboardInterrupt:
        return 130
    finally:
        ex.remove_node(node)
        node.destroy_node()
        ex.shutdown()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
