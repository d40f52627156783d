"""Standard output for what a command prints, and nothing else.

Fast DDS writes its own log lines (e.g. "[RTPS_TRANSPORT_SHM Error] ... open_and_lock_file
failed", when two processes start the shared-memory transport at once on a busy machine) from
C++ to the process's file descriptor 1. In a command whose output a program reads (`lhd echo T |
head -n 1`, `--json`), such a line would be taken for the output: CI failed on it (2026-11-29
and -30). `reserve_stdout()` points file descriptor 1, where C++ code and child processes that
inherit it write, at stderr, and gives Python's sys.stdout a private copy of the real standard
output. Call it before rclpy starts. Where sys.stdout is not the process's own (a caller in the
same process captures it, as pytest's capsys does), it changes nothing: the descriptors belong to
that caller."""
from __future__ import annotations

import os
import sys


def reserve_stdout() -> bool:
    """True when the switch was made."""
    if sys.stdout is not sys.__stdout__ or sys.stdout is None:
        return False
    sys.stdout.flush()
    out_fd = os.dup(1)
    os.dup2(2, 1)
    sys.stdout = os.fdopen(out_fd, "w", encoding=sys.stdout.encoding or "utf-8", errors="replace", closefd=True)
    return True
