"""The lock files (scripts/lock) pin every dependency pyproject.toml names, within its range, by
exact version and hash -- what ./scripts/*, CI and the Dockerfile install."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;\\]+)\s*(?:;\s*([^\\]*?))?\s*\\?$")


def pins(lock: Path) -> dict[str, list[tuple[str, str, int]]]:
    """name -> [(version, marker, hashes)] of a pip requirements file with hashes (a universal
    lock pins some packages once per Python version range, each under its marker)."""
    found: dict[str, list[tuple[str, str, int]]] = {}
    name = ""
    for line in lock.read_text().splitlines():
        if match := PIN.match(line):
            name = canonicalize_name(match[1])
            found.setdefault(name, []).append((match[2], match[3] or "", 0))
        elif line.strip().startswith("--hash=sha256:"):
            version, marker, hashes = found[name][-1]
            found[name][-1] = (version, marker, hashes + 1)
        elif line.strip() and not line.lstrip().startswith("#"):
            raise AssertionError(f"{lock.name}: not a pin, a hash or a comment: {line!r}")
    return found


def extra(name: str) -> list[Requirement]:
    """An extra's requirements, its references to the project's other extras expanded."""
    found = []
    for text in PYPROJECT["project"]["optional-dependencies"][name]:
        requirement = Requirement(text)
        if canonicalize_name(requirement.name) == "quadsynth":
            found += [r for other in sorted(requirement.extras) for r in extra(other)]
        else:
            found.append(requirement)
    return found


def wanted(extras: tuple[str, ...]) -> list[Requirement]:
    names = [*PYPROJECT["project"]["dependencies"], *PYPROJECT["build-system"]["requires"]]
    return [Requirement(r) for r in names] + [r for name in extras for r in extra(name)]


@pytest.mark.parametrize(("lock", "extras"), [("requirements.lock", ("service",)),
                                               ("requirements-dev.lock", ("dev",))])
def test_the_lock_pins_every_dependency_within_its_range_with_hashes(lock: str,
                                                                     extras: tuple[str, ...]) -> None:
    pinned = pins(REPO / lock)
    for requirement in wanted(extras):
        name = canonicalize_name(requirement.name)
        assert name in pinned, f"{lock} lacks {name} (pyproject.toml): run ./scripts/lock"
        for version, _, _ in pinned[name]:
            assert requirement.specifier.contains(version, prereleases=True), \
                f"{lock} pins {name}=={version}, outside {requirement.specifier}: run ./scripts/lock"
    assert {"numba", "llvmlite", "numpy", "setuptools"} <= set(pinned)  # the compiled core and its build
    unhashed = [name for name, versions in pinned.items() if any(h == 0 for _, _, h in versions)]
    assert not unhashed


def test_the_dev_extra_holds_every_other_extra() -> None:
    """./scripts/test (the dev lock) tests the service, the client and the previews."""
    others = set(PYPROJECT["project"]["optional-dependencies"]) - {"dev"}
    assert {canonicalize_name(r.name) for r in extra("dev")} >= \
        {canonicalize_name(r.name) for name in others for r in extra(name)}


def test_the_runtime_lock_agrees_with_the_dev_lock() -> None:
    """The image and the tests run the same versions of what they share."""
    runtime, dev = pins(REPO / "requirements.lock"), pins(REPO / "requirements-dev.lock")
    assert set(runtime) <= set(dev)
    assert {n: sorted(v[:2] for v in vs) for n, vs in runtime.items()} == \
        {n: sorted(v[:2] for v in dev[n]) for n in runtime}
