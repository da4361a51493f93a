"""Animal libraries held in memory by the service, loaded once at start-up.

Libraries are artifact files (:mod:`synth_core.build.artifact`) in the library directory
(``QUADSYNTH_LIBRARY_DIR``; default a per-user data directory, :func:`library_dir`): every
``*.qslib.npz`` there is loaded. The built-in horse and dog are built into it first when missing
(about a second each), so a fresh install serves out of the box.

Readiness (``GET /readyz``) is true only when the service can serve what it was configured for:
every animal in ``QUADSYNTH_LIBRARIES`` (default: the built-in ones) loaded, and every library
file in the directory loaded. A missing or failed library does not stop the process (the others
still serve, and the reason is visible) but keeps ``/readyz`` at 503 with a status per library,
so health checks and load balancers send it no traffic. Reasons name files, never server paths.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import synth_core
from api_schemas import LibraryStatus, LibrarySummary
from synth_core.build.artifact import SUFFIX, Library, LibraryFileError, load_library, save_library
from synth_core.builtin import BUILTIN_ANIMALS
from synth_core.export.gltf import mesh_glb
from synth_core.export.mesh import standing_rotations
from synth_core.runtime.bank import Bank, build_bank

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


def required_animals() -> tuple[str, ...]:
    """``QUADSYNTH_LIBRARIES`` (comma-separated animals that must be loaded for readiness);
    default the built-in animals."""
    raw = os.environ.get("QUADSYNTH_LIBRARIES")
    if raw is None:
        return tuple(BUILTIN_ANIMALS)
    return tuple(name.strip() for name in raw.split(",") if name.strip())


# The modules a built-in library is made by: a file built by other code than these is stale.
_BUILDERS = ("build", "builtin", "motion/contacts.py", "runtime/bank.py")


@functools.cache
def builtin_source() -> str:
    """A digest of the code that builds the built-in animals (written beside each built file)."""
    root = Path(synth_core.__file__).parent
    files = sorted(f for name in _BUILDERS
                   for f in ((root / name).glob("*.py") if (root / name).is_dir() else [root / name]))
    digest = hashlib.sha256()
    for f in files:
        digest.update(f.name.encode() + b"\0" + f.read_bytes())
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


def summarize(library: Library, path: Path) -> LibrarySummary:
    skeleton = library.skeleton
    return LibrarySummary(
        animal=library.animal,
        joints=skeleton.n_joints,
        feet={foot.name: skeleton.names[foot.end_effector] for foot in skeleton.feet},
        fps=library.fps,
        gaits=list(library.maps),
        source=path.name,  # a file name, not the server's path
    )


@dataclass
class LibraryRegistry:
    directory: Path
    required: tuple[str, ...] = field(default_factory=required_animals)
    libraries: dict[str, Library] = field(default_factory=dict)
    summaries: dict[str, LibrarySummary] = field(default_factory=dict)
    banks: dict[str, Bank] = field(default_factory=dict)  # what synthesis reads, per animal
    errors: dict[str, str] = field(default_factory=dict)  # file name -> why it was not loaded
    meshes: dict[str, bytes] = field(default_factory=dict)  # animal -> its skinned mesh, a .glb
    mesh_errors: dict[str, str] = field(default_factory=dict)  # animal -> why it has no mesh
    loaded: bool = False  # loading is done (whatever its outcome: see complete)

    def _reason(self, exc: BaseException) -> str:
        """``exc``'s message with the directory left out: it may be shown to any client."""
        return str(exc).replace(f"{self.directory}{os.sep}", "").replace(str(self.directory), "<library dir>")

    def _fail(self, path: Path, reason: str) -> None:
        self.errors[path.name] = reason
        log.error("library not loaded: %s: %s", path, reason)

    def load(self) -> None:
        try:
            ensure_builtin_libraries(self.directory)
        except OSError as exc:  # e.g. a read-only directory: what is there may still serve
            log.error("cannot build the missing built-in libraries in %s: %s", self.directory, exc)
        for path in sorted(self.directory.glob(f"*{SUFFIX}")):
            try:
                library = load_library(path)
            except LibraryFileError as exc:
                self._fail(path, self._reason(exc))
                continue
            if library.animal in self.libraries:
                self._fail(path, f"a library named {library.animal!r} is already loaded")
                continue
            self.libraries[library.animal] = library
            self.summaries[library.animal] = summarize(library, path)
            self.banks[library.animal] = build_bank(library)
            # Made once here (some tens of ms), so the route only sends bytes.
            try:
                bind = standing_rotations(library.skeleton, library.idle.rotations[0])
                self.meshes[library.animal] = mesh_glb(library.skeleton, library.animal, bind)
            except ValueError as exc:  # the library still serves motion; its mesh route says why not
                self.mesh_errors[library.animal] = str(exc)
                log.error("no mesh for %s: %s", library.animal, exc)
        self.loaded = True

    @property
    def complete(self) -> bool:
        """Every configured library loaded and every library file with it."""
        return self.loaded and not self.errors and all(a in self.libraries for a in self.required)

    def status(self) -> list[LibraryStatus]:
        """One entry per loaded or configured animal and per file that failed, in that order."""
        animals = [*self.libraries, *(a for a in self.required if a not in self.libraries)]
        states = [LibraryStatus(name=a, state="loaded", reason="") if a in self.libraries else LibraryStatus(
            name=a, state="missing",
            reason=f"configured (QUADSYNTH_LIBRARIES) but no library file for {a!r} was loaded")
            for a in animals]
        return states + [LibraryStatus(name=n, state="failed", reason=r) for n, r in self.errors.items()]
