"""How many cores this process may use: the CPU quota of its cgroup, not the host's core count.

A container limited to 2 CPUs on a 64-core host sees 64 in ``os.cpu_count()`` and ``nproc``
(which only reads the affinity mask); one worker process and one numba thread per host core there
would be throttled by the quota. Read: cgroup v2 ``cpu.max`` ("max 100000" or "QUOTA PERIOD"),
else cgroup v1 ``cpu.cfs_quota_us`` / ``cpu.cfs_period_us`` (quota -1: none), then capped by
the affinity mask. A fractional quota rounds up (1.5 CPUs: 2 processes sharing it).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

CGROUP = Path("/sys/fs/cgroup")


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def _own_cgroup_v2(root: Path, proc_cgroup: Path) -> Path:
    """This process's cgroup v2 directory (``0::/path`` in /proc/self/cgroup); in a container
    with its own cgroup namespace the path is ``/`` and the root is it."""
    for line in (_read(proc_cgroup) or "").splitlines():
        if line.startswith("0::"):
            own = root / line[3:].lstrip("/")
            if own.is_dir():
                return own
    return root


def quota_cpus(root: Path = CGROUP, proc_cgroup: Path = Path("/proc/self/cgroup")) -> float | None:
    """The CPU quota in cores (the tightest of this cgroup's and its ancestors'), or None when
    there is none (or no cgroup to read)."""
    own = _own_cgroup_v2(root, proc_cgroup)
    quotas = []
    for directory in [own, *(p for p in own.parents if p.is_relative_to(root))]:
        quota, _, period = (_read(directory / "cpu.max") or "max").partition(" ")
        if quota != "max":
            quotas.append(int(quota) / int(period or "100000"))
    for v1 in (root / "cpu,cpuacct", root / "cpu"):
        quota_us, period_us = _read(v1 / "cpu.cfs_quota_us"), _read(v1 / "cpu.cfs_period_us")
        if quota_us is not None and period_us is not None and int(quota_us) > 0:
            quotas.append(int(quota_us) / int(period_us))
            break
    return min(quotas) if quotas else None


def available_cpus(root: Path = CGROUP, proc_cgroup: Path = Path("/proc/self/cgroup")) -> int:
    """Cores this process may use: the cgroup quota rounded up, at most the affinity mask."""
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    quota = quota_cpus(root, proc_cgroup)
    return max(1, min(affinity, math.ceil(quota))) if quota is not None else max(1, affinity)
