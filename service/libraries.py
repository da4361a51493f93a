"""Animal libraries held in memory by the service, loaded once at start-up.

Libraries are artifact files (:mod:`synth_core.build.artifact`) in the library directory
(:mod:`synth_core.build.library_store`): every ``*.qslib.npz`` there is loaded. The built-in
horse and dog are built into it first when missing (about a second each), so a fresh install
serves out of the box.

Readiness (``GET /readyz``) is true only when the service can serve what it was configured for:
every animal in ``QUADSYNTH_LIBRARIES`` (default: the built-in ones) loaded, and every library
file in the directory loaded. A missing or failed library does not stop the process (the others
still serve, and the reason is visible) but keeps ``/readyz`` at 503 with a status per library,
so health checks and load balancers send it no traffic. Reasons name files, never server paths.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

from api_schemas import LibraryStatus, LibrarySummary
from synth_core.build.artifact import SUFFIX, Library, LibraryFileError, load_library
from synth_core.build.library_store import ensure_builtin_libraries, library_dir
from synth_core.builtin import BUILTIN_ANIMALS
from synth_core.export.gltf import mesh_glb
from synth_core.export.mesh import standing_rotations
from synth_core.runtime.bank import Bank, build_bank

__all__ = ["LibraryRegistry", "library_dir", "required_animals", "summarize"]

log = logging.getLogger("quadsynth.libraries")


def required_animals() -> tuple[str, ...]:
    """``QUADSYNTH_LIBRARIES`` (comma-separated animals that must be loaded for readiness);
    default the built-in animals."""
    raw = os.environ.get("QUADSYNTH_LIBRARIES")
    if raw is None:
        return tuple(BUILTIN_ANIMALS)
    return tuple(name.strip() for name in raw.split(",") if name.strip())


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
