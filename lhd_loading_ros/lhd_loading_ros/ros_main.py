"""The one `main()` of every node: init, spin, clean shutdown on Ctrl-C / SIGTERM, and a
clear message (exit status 2) for a bad parameter or config instead of a traceback."""
from __future__ import annotations

from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException


def number_param(node, name: str, lo: float, hi: float, integer: bool = False):
    """A declared numeric parameter, checked: raises ValueError naming it and the expected range
    (run_node turns that into a clear message and exit status 2)."""
    v = node.get_parameter(name).value
    ok_type = isinstance(v, int) if integer else isinstance(v, (int, float))
    if isinstance(v, bool) or not ok_type or not (lo <= v <= hi):
        kind = "an integer" if integer else "a number"
        raise ValueError(f"parameter '{name}' = {v!r} is invalid; expected {kind} in [{lo}, {hi}]")
    return int(v) if integer else float(v)


def run_node(make_node: Callable, name: str, args=None, before_destroy: Callable | None = None) -> int:
    rclpy.init(args=args)
    node = None
    try:
        node = make_node()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as exc:
        print(f"{name}: {exc}", flush=True)
        return 2
    finally:
        if node is not None:
            if before_destroy is not None:
                before_destroy(node)
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
