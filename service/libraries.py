"""Animal libraries held in memory by the service, loaded once at start-up.

A library is one file per animal in the library directory (``QUADSYNTH_LIBRARY_DIR``, default
``./library``). The artifact format and its loader arrive with the speed-map issue; until then
the directory is scanned and nothing is loaded, so ``/v1/libraries`` answers an empty list.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from api_schemas import LibrarySummary

DEFAULT_LIBRARY_DIR = "library"


def library_dir() -> Path:
    return Path(os.environ.get("QUADSYNTH_LIBRARY_DIR", DEFAULT_LIBRARY_DIR))


@dataclass
class LibraryRegistry:
    directory: Path
    summaries: dict[str, LibrarySummary] = field(default_factory=dict)
    loaded: bool = False

    def load(self) -> None:
        """Load every library artifact in the directory (none are defined yet)."""
        self.summaries = {}
        self.loaded = True
