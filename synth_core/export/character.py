"""One synthesized character as a :class:`Motion` of its own (scaled) skeleton; BVH per character,
each with a ``<id>.contacts.json`` sidecar of its gaits and foot contacts
(:mod:`synth_core.export.annotations`; ``quadsynth preview`` reads it)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from synth_core.export.annotations import character_annotations
from synth_core.motion import bvh
from synth_core.motion.clip import Motion
from synth_core.motion.skeleton import Skeleton
from synth_core.runtime.synthesis import Result


def scaled_skeleton(skeleton: Skeleton, scale: float) -> Skeleton:
    """The skeleton with every bone ``scale`` times as long (a character of scale h)."""
    return replace(skeleton, offsets=skeleton.offsets * scale)


def character_motion(skeleton: Skeleton, result: Result, c: int, fps: float, name: str = "") -> Motion:
    return Motion(scaled_skeleton(skeleton, float(result.scales[c])), result.root_pos[c],
                  result.rotations[c], fps, result.contacts[c], name)


def safe_name(name: str) -> str:
    """A file name from a character id (anything but letters, digits, ``-_.`` becomes ``_``)."""
    cleaned = re.sub(r"[^A-Za-z0-9_.-]", "_", name).strip(".")
    return cleaned or "_"


def write_bvh_files(skeleton: Skeleton, result: Result, ids: list[str], out: Path, fps: float,
                    progress: Callable[[int, int], None] | None = None) -> list[Path]:
    """``out/<id>.bvh`` (centimetres) and ``out/<id>.contacts.json`` for every character synthesized."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for c, name in enumerate(ids):
        path = out / f"{safe_name(name)}.bvh"
        bvh.write(character_motion(skeleton, result, c, fps, name), path, unit="cm")
        sidecar = path.with_name(f"{path.stem}.contacts.json")
        sidecar.write_text(json.dumps(character_annotations(result, c, fps, name)))
        written.append(path)
        if progress:
            progress(c + 1, len(ids))
    return written
