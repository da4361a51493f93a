"""Animal libraries held in memory by the service, loaded once at start-up.

Today these are the built-in animals' skeletons (:mod:`synth_core.library`). Speed maps and the
motion graph join them when the library artifact exists (issue 4); artifacts will then be read
from the library directory (``QUADSYNTH_LIBRARY_DIR``, default ``./library``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from api_schemas import LibrarySummary
from synth_core.library import BUILTIN_ANIMALS, LIBRARY_FPS
from synth_core.skeleton import Skeleton

DEFAULT_LIBRARY_DIR = "library"


def library_dir() -> Path:
    return Path(os.environ.get("QUADSYNTH_LIBRARY_DIR", DEFAULT_LIBRARY_DIR))


def summarize(animal: str, skeleton: Skeleton) -> LibrarySummary:
    return LibrarySummary(
        animal=animal,
        joints=skeleton.n_joints,
        feet={foot.name: skeleton.names[foot.end_effector] for foot in skeleton.feet},
        fps=LIBRARY_FPS,
        gaits=[],
        source="built-in",
    )


@dataclass
class LibraryRegistry:
    directory: Path
    skeletons: dict[str, Skeleton] = field(default_factory=dict)
    summaries: dict[str, LibrarySummary] = field(default_factory=dict)
    loaded: bool = False

    def load(self) -> None:
        """Build the built-in animals' skeletons (milliseconds; no files needed)."""
        self.skeletons = {animal: make() for animal, make in BUILTIN_ANIMALS.items()}
        self.summaries = {animal: summarize(animal, skel) for animal, skel in self.skeletons.items()}
        self.loaded = True
