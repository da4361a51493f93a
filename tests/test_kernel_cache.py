"""numba's cache is kept per version of the whole core: a kernel compiled with a helper from
another module is compiled anew when only that module changes (numba checks only the kernel's own
file, so an upgrade would otherwise run the old helper from the cache)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import synth_core
from synth_core.compiled import jit

# foot_kernels.ground_targets (foot_kernels.py) calls ground_kernels.ground_at (ground_kernels.py):
# the planted foot of a flat grid 0.25 m high, as the kernel compiled (and cached) gives it.
PROBE = """
import synth_core, sys
assert synth_core.__file__.startswith(sys.argv[1]), synth_core.__file__
import numpy as np
from synth_core.compiled import foot_kernels
targets = np.zeros((4, 4, 3)); contacts = np.ones((4, 4), bool)
foot_kernels.ground_targets(targets, contacts, np.full((2, 2), 0.25), 0.0, 0.0, 1.0, 1.0, np.empty(4))
print(targets[0, 0, 1])
"""


def _copy_of_the_core(tmp_path: Path) -> Path:
    core = tmp_path / "src" / "synth_core"
    shutil.copytree(Path(synth_core.__file__).parent, core, ignore=shutil.ignore_patterns("__pycache__"))
    return core


def _probe(core: Path, cache: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(core.parent), NUMBA_CACHE_DIR=str(cache))
    out = subprocess.run([sys.executable, "-c", PROBE, str(core)], env=env, cwd=core.parent,
                         capture_output=True, text=True, check=True, timeout=600)
    return float(out.stdout.split()[-1])


def test_the_stamp_changes_with_any_module_of_the_core(tmp_path: Path) -> None:
    core = _copy_of_the_core(tmp_path)
    before = jit.source_stamp(core)
    assert jit.source_stamp(core) == before
    helper = core / "compiled" / "ground_kernels.py"
    helper.write_text(helper.read_text() + "\n# changed\n")
    assert jit.source_stamp(core) != before


@pytest.mark.skipif(not jit.AVAILABLE, reason="numba is not installed")
def test_a_kernel_is_compiled_anew_when_only_a_helper_in_another_module_changes(tmp_path: Path) -> None:
    core, cache = _copy_of_the_core(tmp_path), tmp_path / "cache"
    assert _probe(core, cache) == pytest.approx(0.25)
    assert _probe(core, cache) == pytest.approx(0.25)  # from the cache
    helper = core / "compiled" / "ground_kernels.py"
    source = helper.read_text()
    body = "    return float(near * (1.0 - v) + far * v)\n"
    assert body in source
    helper.write_text(source.replace(body, "    return float(near * (1.0 - v) + far * v) + 0.5\n"))
    assert _probe(core, cache) == pytest.approx(0.75)  # ground_at's new source, not the cached kernel
    assert sorted(p.name.split("-")[0] for p in cache.iterdir()) == ["numba", "numba"]
