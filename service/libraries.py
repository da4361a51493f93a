"""Animal libraries held in memory by the service, loaded once at start-up.

Libraries are artifact files (:mod:`synth_core.artifact`) in the library directory
(``QUADSYNTH_LIBRARY_DIR``, default ``./library``): every ``*.qslib.npz`` there is loaded. The
built-in horse and dog are built into it first when missing (about a second each), so a fresh
checkout serves out of the box. A file that fails validation is skipped with a logged reason;
the others still load.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

from api_schemas import LibrarySummary
from synth_core.artifact import SUFFIX, Library, LibraryFileError, load_library, save_library
from synth_core.bank import Bank, build_bank
from synth_core.export.gltf import mesh_glb
from synth_core.export.mesh import standing_rotations
from synth_core.library import BUILTIN_ANIMALS

DEFAULT_LIBRARY_DIR = "library"
log = logging.getLogger("quadsynth.libraries")


def library_dir() -> Path:
    return Path(os.environ.get("QUADSYNTH_LIBRARY_DIR", DEFAULT_LIBRARY_DIR))


def ensure_builtin_libraries(directory: Path) -> list[Path]:
    """Build and save the built-in animals' libraries that are missing; returns the new files."""
    from synth_core.build import build_builtin

    built = []
    for animal in BUILTIN_ANIMALS:
        path = directory / f"{animal}{SUFFIX}"
        if not path.exists():
            log.info("building the built-in %s library into %s", animal, path)
            built.append(save_library(build_builtin(animal), path))
    return built


def builtin_library(animal: str) -> Library:
    """A built-in animal's library: its file in the library directory, else built now."""
    from synth_core.build import build_builtin

    path = library_dir() / f"{animal}{SUFFIX}"
    return load_library(path) if path.exists() else build_builtin(animal)


def summarize(library: Library, path: Path) -> LibrarySummary:
    skeleton = library.skeleton
    return LibrarySummary(
        animal=library.animal,
        joints=skeleton.n_joints,
        feet={foot.name: skeleton.names[foot.end_effector] for foot in skeleton.feet},
        fps=library.fps,
        gaits=list(library.maps),
        source=str(path),
    )


@dataclass
class LibraryRegistry:
    directory: Path
    libraries: dict[str, Library] = field(default_factory=dict)
    summaries: dict[str, LibrarySummary] = field(default_factory=dict)
    banks: dict[str, Bank] = field(default_factory=dict)  # what synthesis reads, per animal
    errors: dict[str, str] = field(default_factory=dict)  # file -> why it was not loaded
    meshes: dict[str, bytes] = field(default_factory=dict)  # animal -> its skinned mesh, a .glb
    mesh_errors: dict[str, str] = field(default_factory=dict)  # animal -> why it has no mesh
    loaded: bool = False

    def load(self) -> None:
        ensure_builtin_libraries(self.directory)
        for path in sorted(self.directory.glob(f"*{SUFFIX}")):
            try:
                library = load_library(path)
            except LibraryFileError as exc:
                self.errors[str(path)] = str(exc)
                log.error("library not loaded: %s", exc)
                continue
            if library.animal in self.libraries:
                self.errors[str(path)] = f"a library named {library.animal!r} is already loaded"
                log.error("library not loaded: %s: %s", path, self.errors[str(path)])
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
