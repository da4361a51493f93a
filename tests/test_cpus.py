"""The core count from the cgroup's CPU quota, on fake cgroup trees (v2 and v1)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from service.cpus import available_cpus, quota_cpus

AFFINITY = len(os.sched_getaffinity(0))


def cgroup_v2(tmp_path: Path, **cpu_max: str) -> tuple[Path, Path]:
    """A cgroup v2 tree: {relative dir: cpu.max}, and a /proc/self/cgroup naming the deepest."""
    root = tmp_path / "cgroup"
    root.mkdir()
    for where, value in cpu_max.items():
        directory = root / where.replace("__", "/") if where != "root" else root
        directory.mkdir(parents=True, exist_ok=True)
        (directory / "cpu.max").write_text(value + "\n")
    deepest = max(cpu_max, key=lambda w: w.count("__") + (w != "root"))
    proc = tmp_path / "proc_cgroup"
    proc.write_text("0::/" + ("" if deepest == "root" else deepest.replace("__", "/")) + "\n")
    return root, proc


@pytest.mark.parametrize(("cpu_max", "quota"), [
    ({"root": "max 100000"}, None),
    ({"root": "200000 100000"}, 2.0),
    ({"root": "150000 100000"}, 1.5),
    ({"root": "50000 100000"}, 0.5),
    ({"pods": "max 100000", "pods__replica": "300000 100000"}, 3.0),   # the process's own cgroup
    ({"pods": "100000 100000", "pods__replica": "max 100000"}, 1.0),   # an ancestor's quota binds too
    ({"pods": "400000 100000", "pods__replica": "200000 50000"}, 4.0),  # the tightest of the two
])
def test_cgroup_v2_quota(tmp_path: Path, cpu_max: dict[str, str], quota: float | None) -> None:
    root, proc = cgroup_v2(tmp_path, **cpu_max)
    assert quota_cpus(root, proc) == quota
    expected = AFFINITY if quota is None else max(1, min(AFFINITY, -(-quota // 1)))
    assert available_cpus(root, proc) == expected


def test_cgroup_v1_quota_and_no_quota(tmp_path: Path) -> None:
    cpu = tmp_path / "cpu,cpuacct"
    cpu.mkdir()
    (cpu / "cpu.cfs_period_us").write_text("100000\n")
    (cpu / "cpu.cfs_quota_us").write_text("-1\n")
    assert quota_cpus(tmp_path, tmp_path / "none") is None
    (cpu / "cpu.cfs_quota_us").write_text("100000\n")
    assert quota_cpus(tmp_path, tmp_path / "none") == 1.0 and available_cpus(tmp_path, tmp_path / "none") == 1


def test_no_cgroup_files_means_the_affinity_mask(tmp_path: Path) -> None:
    assert quota_cpus(tmp_path / "absent", tmp_path / "absent") is None
    assert available_cpus(tmp_path / "absent", tmp_path / "absent") == AFFINITY
