"""The core runs on its own dependencies (pyproject.toml's ``dependencies``): the web service, the
Python client and the previews are extras (``quadsynth[service]``, ``[client]``, ``[preview]``).

Each check runs in a fresh interpreter whose imports of every installed package outside the core's
dependency closure are refused by a meta-path finder, as if only ``pip install quadsynth`` had
been done (the test venv holds every extra, so an accidental import would otherwise go unseen)."""

from __future__ import annotations

import importlib.metadata as metadata
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

REPO = Path(__file__).resolve().parents[1]
PROJECT_PACKAGES = ("synth_core", "api_schemas", "service", "quadsynth")
WEB = {"fastapi", "starlette", "uvicorn", "pydantic"}

# Run before anything else in the child: the finder refuses the blocked top-level names (argv[1],
# comma-separated), and the child reports which of them were already loaded at start (.pth files).
REFUSE = """
import importlib.abc, json, sys
BLOCKED = frozenset(sys.argv.pop(1).split(","))
class Refuse(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r} (refused: not a core dependency)", name=name)
        return None
PRELOADED = {m for m in BLOCKED if m in sys.modules}
sys.meta_path.insert(0, Refuse())
def refused_and_loaded():
    return sorted({n.partition(".")[0] for n in sys.modules} & BLOCKED - PRELOADED)
try:
    import fastapi  # the finder must really refuse, else this test proves nothing
    raise SystemExit("fastapi imported although refused")
except ModuleNotFoundError:
    pass
"""


def core_closure() -> set[str]:
    """The distributions ``pip install quadsynth`` (no extra) brings: the core's dependencies and
    theirs, as installed here."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    todo = [Requirement(r) for r in project["dependencies"]]
    seen: set[str] = set()
    while todo:
        requirement = todo.pop()
        if requirement.marker is not None and not requirement.marker.evaluate({"extra": ""}):
            continue
        name = canonicalize_name(requirement.name)
        if name not in seen:
            seen.add(name)
            todo += [Requirement(r) for r in metadata.requires(name) or []]
    return seen


def outside_the_core(*allowed_project_packages: str) -> set[str]:
    """Top-level import names of every installed distribution outside the core's closure, and the
    project's packages other than those allowed."""
    core = core_closure()
    names = {module for module, dists in metadata.packages_distributions().items()
             if not any(canonicalize_name(d) in core for d in dists)}
    return (names - set(PROJECT_PACKAGES)) | (set(PROJECT_PACKAGES) - set(allowed_project_packages))


def run_refusing(blocked: set[str], code: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", REFUSE + code, ",".join(sorted(blocked)), *args],
                          cwd=REPO, capture_output=True, text=True, timeout=900)


def test_the_web_packages_are_outside_the_core() -> None:
    """The extras' packages are not dragged into the core by a dependency of a dependency."""
    blocked = outside_the_core("synth_core")
    assert WEB | {"httpx", "msgpack", "websockets", "matplotlib"} <= blocked
    assert {"numpy", "scipy", "numba", "llvmlite", "pygltflib"}.isdisjoint(blocked)


def test_every_synth_core_module_imports_with_only_the_core_dependencies() -> None:
    code = """
import importlib, pkgutil
import synth_core
names = [m.name for m in pkgutil.walk_packages(synth_core.__path__, "synth_core.")]
for name in names:
    importlib.import_module(name)
print(json.dumps({"modules": names, "refused_and_loaded": refused_and_loaded(), "file": synth_core.__file__}))
"""
    done = run_refusing(outside_the_core("synth_core"), code)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.splitlines()[-1])
    assert Path(report["file"]).is_relative_to(REPO)
    # every subpackage of the paper's layout was walked, not just the top
    assert {"synth_core.runtime.synthesis", "synth_core.compiled.kernels", "synth_core.export.gltf",
            "synth_core.build.artifact", "synth_core.quality.evaluate"} <= set(report["modules"])
    assert report["refused_and_loaded"] == []


def test_the_core_runs_without_numba_on_its_numpy_reference(tmp_path: Path) -> None:
    """numba is installed with the core (the compiled kernels, thousands of times faster), but the
    core does not need it: refused, every module imports and a herd is synthesized by the reference
    (the kernels' own source, interpreted), the motion the kernels make."""
    code = """
import importlib, pkgutil
import numpy as np
import synth_core
for module in pkgutil.walk_packages(synth_core.__path__, "synth_core."):
    importlib.import_module(module.name)
from synth_core.build.animals import build_builtin
from synth_core.compiled import kernels
from synth_core.quality import herd_sim
from synth_core.runtime.bank import build_bank
from synth_core.runtime.synthesis import synthesize
result = synthesize(build_bank(build_builtin("dog")), herd_sim.simulate(3, 90, seed=1))
np.savez(sys.argv[1], rotations=result.rotations, gait=result.gait, compiled=kernels.AVAILABLE)
print(json.dumps(refused_and_loaded()))
"""
    for name, blocked in (("reference", outside_the_core("synth_core") | {"numba", "llvmlite"}),
                          ("compiled", outside_the_core("synth_core"))):
        done = run_refusing(blocked, code, str(tmp_path / f"{name}.npz"))
        assert done.returncode == 0, done.stderr[-3000:]
        assert json.loads(done.stdout.splitlines()[-1]) == []
    with np.load(tmp_path / "reference.npz") as reference, np.load(tmp_path / "compiled.npz") as compiled:
        assert not reference["compiled"] and compiled["compiled"]
        np.testing.assert_array_equal(reference["gait"], compiled["gait"])
        np.testing.assert_allclose(reference["rotations"], compiled["rotations"], atol=1e-4)


@pytest.fixture(scope="module")
def core_cli_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A library file and a small herd's trajectories, made with the CLI under the refusal."""
    out = tmp_path_factory.mktemp("core_cli")
    files = {"library": out / "dog.qslib.npz", "herd": out / "herd.npz"}
    code = "from quadsynth.cli import main; raise SystemExit(main(sys.argv[1:]))"
    blocked = outside_the_core("synth_core", "quadsynth")
    for argv in (["build", "--animal", "dog", "--out", str(files["library"])],
                 ["crowd-sim", "--characters", "3", "--frames", "60", "--seed", "2",
                  "--out", str(files["herd"])]):
        done = run_refusing(blocked, code, *argv)
        assert done.returncode == 0, (argv, done.stderr[-3000:])
    assert all(f.exists() for f in files.values())
    return files


def test_the_cli_synthesizes_from_a_library_file_with_only_the_core_dependencies(
        core_cli_files: dict[str, Path], tmp_path: Path) -> None:
    """build, crowd-sim and synth (BVH and glTF out) import neither the service, the client nor
    the web packages; the motion is the one the full install makes."""
    code = ("from quadsynth.cli import main; code = main(sys.argv[1:]); "
            "print(json.dumps(refused_and_loaded())); raise SystemExit(code)")

    def argv(name: str) -> list[str]:
        return ["synth", "--trajectories", str(core_cli_files["herd"]),
                "--library", str(core_cli_files["library"]), "--seed", "4", "--bvh",
                "--glb", str(tmp_path / f"{name}.glb"), "--out", str(tmp_path / name)]

    done = run_refusing(outside_the_core("synth_core", "quadsynth"), code, *argv("core"))
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout.splitlines()[-1]) == []
    full = subprocess.run([sys.executable, "-c", "import sys; from quadsynth.cli import main; "
                           "raise SystemExit(main(sys.argv[1:]))", *argv("full")],
                          cwd=REPO, capture_output=True, text=True, timeout=900)
    assert full.returncode == 0, full.stderr[-3000:]
    assert len(list((tmp_path / "core").glob("*.bvh"))) == 3 and (tmp_path / "core.glb").stat().st_size > 0
    with np.load(tmp_path / "core" / "motion.npz") as core, \
            np.load(tmp_path / "full" / "motion.npz") as whole:
        assert sorted(core.files) == sorted(whole.files)
        for key in core.files:
            np.testing.assert_array_equal(core[key], whole[key], err_msg=key)


def test_the_cli_synthesizes_a_built_in_animal_without_the_service(
        core_cli_files: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("QUADSYNTH_LIBRARY_DIR", str(tmp_path / "library"))
    code = "from quadsynth.cli import main; raise SystemExit(main(sys.argv[1:]))"
    done = run_refusing(outside_the_core("synth_core", "quadsynth"), code, "synth",
                        "--trajectories", str(core_cli_files["herd"]), "--animal", "dog",
                        "--bvh", "--out", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr[-3000:]
    assert len(list((tmp_path / "out").rglob("*.bvh"))) == 3
