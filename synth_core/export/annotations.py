"""A synthesized character's gaits and foot contacts as a JSON document: the BVH sidecar
``<id>.contacts.json`` and the ``extras`` of its node in a glTF herd hold the same document.

It extends the clips' ``contacts.json`` (:func:`synth_core.motion.contacts.contacts_json`: ``fps``,
``frames``, ``range_convention``, per foot planted ``[start, stop)`` ranges; ``quadsynth
preview`` reads it) with ``gait``: ``[start, stop, name]`` runs of the gait played, a
transition's first half counted to the gait it leaves and its second to the gait it reaches
(:class:`synth_core.runtime.synthesis.Result`), and the character's ``scale``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from synth_core.build.motion_graph import HUBS
from synth_core.motion.contacts import contacts_json
from synth_core.runtime.synthesis import Result


def gait_runs(gait: NDArray[np.integer]) -> list[list[int | str]]:
    """``[start, stop, name]`` for each run of one gait in a character's (T,) hub indices."""
    if gait.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(gait)) + 1
    starts, stops = np.concatenate([[0], cuts]), np.concatenate([cuts, [gait.size]])
    return [[int(a), int(b), HUBS[int(gait[a])]] for a, b in zip(starts, stops, strict=True)]


def character_annotations(result: Result, c: int, fps: float, name: str) -> dict[str, object]:
    """Character ``c``'s document (see the module docstring)."""
    document = contacts_json(result.contacts[c], fps)
    document.update(id=name, scale=float(result.scales[c]), gait=gait_runs(result.gait[c]))
    return document
