"""Levels of detail of a skeleton's motion: which joints a far character still needs.

- ``full``: every joint.
- ``legs_spine``: the root, the spine up to where the legs hang, the four legs and what is below
  the feet -- everything a foot's world position depends on, so the hooves still land where the
  full motion puts them; head, neck and tail are left out (played at the identity rotation).
- ``root_gait``: no joint at all: the root's path, the gait and the contacts (an impostor, or a
  client's own cycle played at the gait).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from synth_core.motion.skeleton import Skeleton

Detail = Literal["full", "legs_spine", "root_gait"]
DETAILS: tuple[Detail, ...] = ("full", "legs_spine", "root_gait")


def detail_joints(skeleton: Skeleton, detail: Detail) -> NDArray[np.int64]:
    """The joints (indices, ascending) a client at ``detail`` is sent."""
    J = skeleton.n_joints
    if detail == "full":
        return np.arange(J)
    if detail == "root_gait":
        return np.zeros(0, np.int64)
    if detail != "legs_spine":
        raise ValueError(f"detail must be one of {', '.join(DETAILS)}, got {detail!r}")
    keep = np.zeros(J, bool)
    for foot in skeleton.foot_joints:
        j = int(foot)
        while j >= 0:  # the foot and every ancestor: what places it
            keep[j] = True
            j = int(skeleton.parents[j])
    below = np.zeros(J, bool)
    below[skeleton.foot_joints] = True
    for j in range(1, J):  # parents come first: what hangs below a foot (its end site) goes too
        below[j] |= below[skeleton.parents[j]]
    return np.flatnonzero(keep | below)
