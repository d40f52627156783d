"""How many CPU cores this process may really use: its affinity mask, capped by a cgroup CPU
quota (a container given "2 CPUs" on a 16-core host sees 16 in os.cpu_count() and in its
affinity, but is throttled to 2). Used for the default number of parallel jobs and for the twin's
warning about too few cores."""
from __future__ import annotations

import os
from pathlib import Path


def quota_cores(cpu_max: str | None = None, cfs_quota_us: str | None = None,
                cfs_period_us: str | None = None) -> int | None:
    """Whole cores a cgroup quota allows (rounded down, at least 1: a 3.5-CPU quota cannot keep
    four busy threads running), or None when unlimited or unknown. cpu_max: cgroup v2's cpu.max
    ("max 100000" or "<quota> <period>"); cfs_quota_us / cfs_period_us: cgroup v1's (quota -1 =
    unlimited)."""
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
    return max(1, q // p)


def _read(path: Path) -> str | None:
    try:
        return path.read_text()
    except OSError:
        return None


def cgroup_dirs(proc_cgroup: str, root: Path = Path("/sys/fs/cgroup")) -> list[Path]:
    """The CPU controller's directories of this process's cgroup and of every cgroup above it
    (a quota set on a parent, e.g. a systemd slice, applies too), from /proc/self/cgroup: the
    v2 line "0::/path", or v1's line naming the cpu controller."""
    dirs = []
    for line in proc_cgroup.splitlines():
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, path = parts
        if controllers == "":                                  # cgroup v2
            base = root
        elif "cpu" in controllers.split(","):                  # cgroup v1 cpu controller
            base = root / "cpu" if (root / "cpu").exists() else root / controllers
        else:
            continue
        rel = Path(path.lstrip("/"))
        for k in range(len(rel.parts), -1, -1):
            dirs.append(base.joinpath(*rel.parts[:k]))
    return dirs


def usable_cores() -> int:
    """min(affinity, the smallest cgroup quota on the way up from this process's cgroup); at least 1."""
    n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    quotas = []
    for d in cgroup_dirs(_read(Path("/proc/self/cgroup")) or "0::/"):
        q = quota_cores(cpu_max=_read(d / "cpu.max"))
        if q is None:
            q = quota_cores(cfs_quota_us=_read(d / "cpu.cfs_quota_us"), cfs_period_us=_read(d / "cpu.cfs_period_us"))
        if q is not None:
            quotas.append(q)
    return max(1, min([n, *quotas]))
