"""argparse types that refuse a bad number at parsing, naming the flag (argparse adds "argument
--seed: ...") and what is expected, with exit status 2, before anything starts."""
from __future__ import annotations

import argparse


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def nonneg_int(text: str) -> int:
    """An integer >= 0 (seeds, counts where 0 means none or no limit)."""
    v = _int(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {v}")
    return v


def pos_int(text: str) -> int:
    """An integer >= 1 (steps, rounds)."""
    v = _int(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {v}")
    return v


def pos_float(text: str) -> float:
    """A finite number > 0 (timeouts, seconds to wait)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}") from None
    if not (v > 0.0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text}")
    return v


def topic_prefix(text: str) -> str:
    """A machine's topic prefix (`--namespace /lhd`): a ROS namespace other than "/", returned as "/name"."""
    ns = "/" + text.strip("/")
    if ns == "/":
        raise argparse.ArgumentTypeError("expected the machine's topic prefix, e.g. /lhd, got " + repr(text))
    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.validate_namespace import validate_namespace

    try:
        validate_namespace(ns)
    except InvalidNamespaceException:
        raise argparse.ArgumentTypeError(f"{text!r} is no ROS namespace: expected letters, digits and '_' in "
                                         "'/'-separated parts, e.g. /lhd or /machine2/lhd") from None
    return ns
