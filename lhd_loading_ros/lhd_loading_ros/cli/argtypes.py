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
