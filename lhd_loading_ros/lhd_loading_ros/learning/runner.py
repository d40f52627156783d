"""Several training seeds in parallel processes (``lhd train --seeds 0-4``)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path


def parse_seeds(text: str) -> list[int]:
    """'0-4' -> [0, 1, 2, 3, 4]; '0,2,5' -> [0, 2, 5]; '3' -> [3]."""
    seeds: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if "-" in part[1:]:
                lo, hi = part.split("-", 1)
                a, b = int(lo), int(hi)
                if b < a:
                    raise ValueError
                seeds.extend(range(a, b + 1))
            else:
                seeds.append(int(part))
    except ValueError:
        raise ValueError(f"seeds {text!r} not understood; expected e.g. '0-4', '0,2,5' or '3'") from None
    if any(s < 0 for s in seeds) or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds {text!r}: expected distinct non-negative integers")
    return seeds


def run_seeds(variant: str, seeds: list[int], out: Path, jobs: int, extra: list[str], per_seed=None) -> int:
    """Run `lhd train` for each seed as a child process, at most `jobs` at a time. Logs go to
    out/seed_N.log. Ctrl-C stops every child (their checkpoints let them resume). per_seed(seed):
    further arguments for that seed's child (e.g. its --branch-from)."""
    if jobs < 1:                     # 0 or less would start none and wait for ever
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    out.mkdir(parents=True, exist_ok=True)
    pending = list(seeds)
    running: dict[int, subprocess.Popen] = {}
    failed = []
    previous = None
    if threading.current_thread() is threading.main_thread():
        # SIGTERM (`timeout`, `kill`, a scheduler) stops the children as Ctrl-C does: they run in their own
        # sessions, so without this they trained on, orphaned (a review, 2026-11-29)
        previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        while pending or running:
            while pending and len(running) < jobs:
                s = pending.pop(0)
                cmd = [sys.executable, "-m", "lhd_loading_ros.cli.main", "train", "--variant", variant, "--seed", str(s),
                       "--out", str(out / f"seed_{s}"), "--no-progress", *extra,
                       *(per_seed(s) if per_seed else [])]
                log = open(out / f"seed_{s}.log", "ab")
                running[s] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
                log.close()
                print(f"seed {s}: started (log {out / f'seed_{s}.log'})", flush=True)
            time.sleep(1.0)
            for s, p in list(running.items()):
                if p.poll() is not None:
                    del running[s]
                    print(f"seed {s}: exit {p.returncode}", flush=True)
                    if p.returncode:
                        failed.append(s)
    except KeyboardInterrupt:
        if previous is not None:         # a second SIGTERM must not cut the children's stop short
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        for p in running.values():
            os.killpg(p.pid, signal.SIGINT)
        for p in running.values():
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
        print("interrupted; rerun the same command to resume from the checkpoints", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if failed:
        failed.sort()                    # in seed order, not in the order the children happened to exit
        reasons: dict[str, list[int]] = {}
        for s in failed:
            reasons.setdefault(_reason(out / f"seed_{s}.log"), []).append(s)
        why = "".join(f"\n  seed{'s' if len(ss) > 1 else ''} {', '.join(map(str, ss))}: {r}" for r, ss in reasons.items())
        print(f"failed seeds: {failed} (their logs: {out}/seed_N.log){why}", file=sys.stderr)
        return 1
    return 0


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def _reason(path: Path, limit: int = 600) -> str:
    """Why a seed's child failed, from its log: its last `lhd train: ...` message with the lines after it
    (a refused config lists its problems), else the log's last line; on one line, at most `limit` chars."""
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return "(no log)"
    if not lines:
        return "(empty log)"
    starts = [i for i, ln in enumerate(lines) if ln.startswith("lhd train:")]
    text = " / ".join(lines[starts[-1]:] if starts else lines[-1:])
    return text if len(text) <= limit else text[: limit - 3] + "..."
