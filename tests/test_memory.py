"""service.memory: a tuned worker process keeps the memory it frees for the next request."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys

import pytest

from service.settings import Settings

# In a fresh process: the RSS a freed 24 MB array gives back, then whether numpy still asks
# for huge pages (turning it off returns the value before).
_PROBE = """
import json, os, sys
import numpy as np
from service import memory
applied = memory.tune() if sys.argv[1] == "tuned" else {}
page = os.sysconf("SC_PAGE_SIZE")
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * page
a = np.ones(3 << 20)  # 24 MiB, every page written
before = rss()
del a
given_back = before - rss()
hugepages = np._core.multiarray._set_madvise_hugepage(False)
print(json.dumps({"applied": applied, "given_back": given_back, "hugepages": hugepages}))
"""


def _probe(mode: str) -> dict[str, object]:
    # Neither set from outside: numpy's import and glibc's start-up read these.
    env = {k: v for k, v in os.environ.items() if k not in ("NUMPY_MADVISE_HUGEPAGE", "GLIBC_TUNABLES")}
    out = subprocess.run([sys.executable, "-c", _PROBE, mode], capture_output=True, text=True, check=True,
                         timeout=120, env=env)
    result: dict[str, object] = json.loads(out.stdout)
    return result


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="the tuning is glibc's malloc and numpy's madvise on Linux")
def test_a_tuned_process_keeps_freed_memory_and_asks_no_huge_pages() -> None:
    default, tuned = _probe("default"), _probe("tuned")
    assert tuned["applied"] == {"numpy_hugepages_off": True, "glibc_malloc": True}
    # Untuned, glibc maps a block this large on its own and unmaps it when freed: the next
    # request faults it in again, zeroed.
    assert isinstance(default["given_back"], int) and default["given_back"] > 20 << 20
    assert isinstance(tuned["given_back"], int) and tuned["given_back"] < 1 << 20
    assert default["hugepages"] is True and tuned["hugepages"] is False


def test_memory_tuning_is_on_by_default_and_can_be_turned_off(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("QUADSYNTH_MEMORY_TUNING", raising=False)
    assert Settings.from_env().memory_tuning is True
    monkeypatch.setenv("QUADSYNTH_MEMORY_TUNING", "0")
    assert Settings.from_env().memory_tuning is False


_KEPT = """
import json, os
import numpy as np
from service import memory
memory.tune()
page = os.sysconf("SC_PAGE_SIZE")
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * page
arrays = [np.ones(1 << 17) for _ in range(100)]  # 100 x 1 MiB from the heap, every page written
del arrays
before, rss_before = memory.kept(), rss()
memory.give_back()
print(json.dumps({"before": before, "after": memory.kept(), "returned": rss_before - rss()}))
"""


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="glibc's malloc statistics")
def test_memory_kept_for_reuse_is_measured_and_given_back() -> None:
    out = subprocess.run([sys.executable, "-c", _KEPT], capture_output=True, text=True, check=True,
                         timeout=120)
    result = json.loads(out.stdout)
    assert result["before"] >= 90 << 20  # the tuned process kept the 100 MiB it freed
    assert result["after"] < 10 << 20 and result["returned"] >= 80 << 20
