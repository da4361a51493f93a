"""Where animal libraries live on disk, and the built-in animals built into it.

The library directory (``QUADSYNTH_LIBRARY_DIR``; default a per-user data directory,
:func:`library_dir`) holds artifact files (:mod:`synth_core.build.artifact`). The built-in horse
and dog are built into it when missing or built by other code (a stamp beside each file names
the code that built it), so a fresh install serves out of the box and an upgrade rebuilds them.
The service loads the whole directory; the CLI reads a built-in animal from it.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
from pathlib import Path

import synth_core
from synth_core.build.artifact import SUFFIX, Library, load_library, save_library
from synth_core.builtin import BUILTIN_ANIMALS

log = logging.getLogger("quadsynth.libraries")


def library_dir() -> Path:
    """``QUADSYNTH_LIBRARY_DIR``, else ``$XDG_DATA_HOME/quadsynth/library`` (XDG base directory
    spec; ``~/.local/share`` when unset): never the working directory, so a ``quadsynth serve``
    started elsewhere finds the same libraries instead of silently building new ones there."""
    configured = os.environ.get("QUADSYNTH_LIBRARY_DIR")
    if configured:
        return Path(configured)
    data_home = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(data_home) / "quadsynth" / "library"


# The code a built-in library is made by (paths in synth_core): a file built by other code than
# this is stale. Whole packages, so that a module added or moved inside them counts too.
# tests/test_libraries.py checks that every synth_core module building a library imports is here.
_BUILDERS = ("__init__.py", "build", "builtin", "motion", "quality/__init__.py", "quality/metrics.py",
             "runtime/__init__.py", "runtime/bank.py")


def builtin_source_files() -> list[Path]:
    """The files :func:`builtin_source` digests."""
    root = Path(synth_core.__file__).parent
    missing = [name for name in _BUILDERS if not (root / name).exists()]
    if missing:  # a module moved: say so instead of a bare FileNotFoundError at every start
        raise RuntimeError(f"library_store._BUILDERS names {missing}, not in {root}: update it")
    return sorted(f for name in _BUILDERS
                  for f in ((root / name).rglob("*.py") if (root / name).is_dir() else [root / name]))


@functools.cache
def builtin_source() -> str:
    """A digest of the code that builds the built-in animals (written beside each built file)."""
    root = Path(synth_core.__file__).parent
    digest = hashlib.sha256()
    for f in builtin_source_files():
        digest.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes())
    return digest.hexdigest()[:16]


def _stamp(path: Path) -> Path:
    return path.with_name(path.name + ".source")


def _current(path: Path) -> bool:
    """A built-in library file built by this code (its stamp says so)."""
    stamp = _stamp(path)
    return path.exists() and stamp.exists() and stamp.read_text().strip() == builtin_source()


def ensure_builtin_libraries(directory: Path) -> list[Path]:
    """Build and save the built-in animals' libraries that are missing or were built by other code
    (an upgrade: the library directory outlives a checkout); returns the new files."""
    from synth_core.build.animals import build_builtin

    built = []
    for animal in BUILTIN_ANIMALS:
        path = directory / f"{animal}{SUFFIX}"
        if not _current(path):
            why = "missing"
            if path.exists():  # kept aside, not lost: it may be the user's own file of that name
                path.replace(path.with_name(path.name + ".old"))
                why = f"built by other code; the old file kept as {path.name}.old"
            log.info("building the built-in %s library into %s (%s)", animal, path, why)
            built.append(save_library(build_builtin(animal), path))
            _stamp(path).write_text(builtin_source() + "\n")
    return built


def builtin_library(animal: str) -> Library:
    """A built-in animal's library: its file in the library directory if this code built it,
    else built now."""
    from synth_core.build.animals import build_builtin

    path = library_dir() / f"{animal}{SUFFIX}"
    return load_library(path) if _current(path) else build_builtin(animal)
