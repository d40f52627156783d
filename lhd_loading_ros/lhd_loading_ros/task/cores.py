"""How many CPU cores this process may really use: its affinity mask, capped by a cgroup CPU
quota (a container given "2 CPUs" on a 16-core host sees 16 in os.cpu_count() and in its
affinity, but is throttled to 2). Used for the default number of parallel jobs and for the twin's
warning about too few cores."""
from __future__ import annotations

import math
import os
from pathlib import Path


def quota_cores(cpu_max: str | None = None, cfs_quota_us: str | None = None,
                cfs_period_us: str | None = None) -> int | None:
    """Cores a cgroup quota allows (rounded up), or None when unlimited or unknown.
    cpu_max: cgroup v2's cpu.max ("max 100000" or "<quota> <period>"); cfs_quota_us /
    cfs_period_us: cgroup v1's (quota -1 = unlimited)."""
    try:
        if cpu_max is not None:
            quota, period = cpu_max.split()[:2]
            if quota == "max":
                return None
            q, p = int(quota), int(period)
        elif cfs_quota_us is not None and cfs_period_us is not None:
            q, p = int(cfs_quota_us.strip()), int(cfs_period_us.strip())
        else:
            return None
    except ValueError:
        return None
    if q <= 0 or p <= 0:
        return None
    return max(1, math.ceil(q / p))


def _read(path: str) -> str | None:
    try:
        return Path(path).read_text()
    except OSError:
        return None


def usable_cores() -> int:
    """min(affinity, cgroup quota); at least 1."""
    n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    q = quota_cores(cpu_max=_read("/sys/fs/cgroup/cpu.max"))
    if q is None:
        q = quota_cores(cfs_quota_us=_read("/sys/fs/cgroup/cpu/cpu.cfs_quota_us"),
                        cfs_period_us=_read("/sys/fs/cgroup/cpu/cpu.cfs_period_us"))
    return max(1, min(n, q) if q is not None else n)
