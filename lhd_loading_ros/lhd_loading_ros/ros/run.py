"""The one `main()` of every node: init, spin, an orderly shutdown on Ctrl-C / SIGTERM, and a
clear message (exit status 2) for a bad parameter or config instead of a traceback.

Why not rclpy's own signal handlers: on SIGINT they shut the context down from a helper thread
*and* chain to Python's handler, so a KeyboardInterrupt lands at an arbitrary bytecode, sometimes
inside a timer callback that is publishing (RCLError: context invalid) or inside the clean-up
that must still reach the hardware (the bridge's stop frame, the policy's last zero command).
That race made a node exit 1 now and then on a plain Ctrl-C. Here the signal only sets a flag;
the spin loop notices it within SPIN_PERIOD_S, and the clean-up runs with the context still
valid, so a node's last messages leave before rclpy shuts down. A second Ctrl-C during the
clean-up is ignored rather than tearing it in half.
"""
from __future__ import annotations

import signal
import threading
from typing import Callable

import rclpy
from rclpy.exceptions import (InvalidParameterException, InvalidParameterTypeException, InvalidParameterValueException,
                               NameValidationException)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

SPIN_PERIOD_S = 0.1     # the longest a stop request waits for the spin loop to see it
# the longest the clean-up may take once a stop was requested: past it the kernel ends the process
# (SIGALRM, whose default action needs no Python: a clean-up stuck inside rclpy holding the GIL
# was seen at 80 % CPU ignoring SIGTERM, a review, 2026-11-28). The launchers kill a node 10 s
# after their SIGTERM as well; a node whose launcher died has only this.
SHUTDOWN_DEADLINE_S = 10


def one_line(exc: Exception) -> str:
    """An exception's message on one line (rclpy's name errors span three, with a caret)."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip() and set(ln.strip()) != {"^"}]
    return " ".join(lines)


def unknown_parameters(node) -> str | None:
    """The parameters given to `node` (`-p name:=value`, or its section of a --params-file) that it never
    declared, as one sentence naming each with the nearest declared name; None when there are none.
    rclpy drops such overrides without a word, so a misspelt name (`-p controler:=tampier`) left the
    default in force while the user believed otherwise (a review, 2026-12-01). rclpy's own parameters
    (use_sim_time, start_type_description_service, qos_overrides.*) are not the node's to declare."""
    import difflib

    overrides = getattr(node, "_parameter_overrides", None) or {}     # rclpy keeps them here (no public getter)
    unknown = sorted(n for n in overrides if not node.has_parameter(n) and not n.startswith("qos_overrides.")
                     and n not in ROS_OWN_PARAMETERS)
    if not unknown:
        return None
    declared = sorted(node._parameters)

    def named(n):
        near = difflib.get_close_matches(n, declared, n=1)
        return f"'{n}'" + (f" (did you mean '{near[0]}'?)" if near else "")

    return (f"unknown parameter{'s' if len(unknown) > 1 else ''} {', '.join(named(n) for n in unknown)}: this node "
            f"declares {', '.join(d for d in declared if d not in ROS_OWN_PARAMETERS)} (their ranges: `describe_parameters`, "
            "docs/ros_nodes.md); a misspelt name would leave the default in force")


# what rclpy declares on every node itself
ROS_OWN_PARAMETERS = ("use_sim_time", "start_type_description_service")


def run_node(make_node: Callable, name: str, args=None, before_destroy: Callable | None = None,
             stop: threading.Event | None = None, shutdown_deadline_s: int = SHUTDOWN_DEADLINE_S) -> int:
    """Run one node until SIGINT/SIGTERM (or `stop` is set); returns the exit status:
    0 after a requested stop, 2 for a bad parameter (message printed). `before_destroy(node)`
    runs while the node can still publish and talk to its hardware. In the main thread the
    clean-up gets `shutdown_deadline_s` s (SIGALRM ends the process past it)."""
    stop = stop or threading.Event()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:        # rclpy's RCLError (a private module's class: not imported by name)
        # a malformed --ros-args (`-p name:=` with no value, an unknown flag): rcl refuses to start
        print(f"{name}: cannot start: {exc}".split(", at /")[0], flush=True)
        return 2
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, lambda *_: stop.set())
    executor = SingleThreadedExecutor()
    node = None
    rc = 0
    try:
        node = make_node()
        unknown = unknown_parameters(node)
        if unknown:
            raise ValueError(unknown)
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD_S)
    except ExternalShutdownException:
        pass
    except ValueError as exc:
        print(f"{name}: {exc}", flush=True)
        rc = 2
    except NameValidationException as exc:
        # a topic, service or namespace parameter (or remap) that is no ROS name: rclpy's three-line message
        # (the name and a caret under the bad character) in one line
        print(f"{name}: {one_line(exc)} (a topic or namespace parameter, or a remap; expected a ROS name: letters, "
              "digits, '_' and '/' separators, not starting with a digit)", flush=True)
        rc = 2
    except (InvalidParameterException, InvalidParameterTypeException, InvalidParameterValueException) as exc:
        # e.g. `-p use_sim_time:=1` (an integer for a bool): rclpy refuses it while the node is made
        print(f"{name}: {one_line(exc)} (`-p name:=true` / `false` for a bool, a decimal point for a float)",
              flush=True)
        rc = 2
    finally:
        main = threading.current_thread() is threading.main_thread()
        if main and shutdown_deadline_s > 0:
            signal.signal(signal.SIGALRM, signal.SIG_DFL)
            signal.alarm(shutdown_deadline_s)
        try:
            if node is not None:
                try:
                    if before_destroy is not None:
                        before_destroy(node)
                finally:
                    executor.remove_node(node)
                    node.destroy_node()
        finally:
            executor.shutdown()
            if rclpy.ok():
                rclpy.shutdown()
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            if main and shutdown_deadline_s > 0:
                signal.alarm(0)
    return rc
