"""Skeleton: joint names, parents in topological order, rest offsets, the four feet; batched FK.

Shapes follow the glossary in :mod:`synth_core`. End Sites of a BVH file are ordinary joints
here (flagged in ``end_site``), so a paw tip can be a foot's end effector and FK covers it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from synth_core import FOOT_NAMES
from synth_core.motion import quat


@dataclass(frozen=True)
class Foot:
    """One foot: its end-effector joint and the limb chain from the limb root down to it."""

    name: str  # one of FOOT_NAMES
    end_effector: int
    chain: tuple[int, ...]  # joint indices, limb root first, end effector last


@dataclass(frozen=True, eq=False)
class Skeleton:
    names: tuple[str, ...]
    parents: NDArray[np.int32]  # (J,)
    offsets: NDArray[np.float32]  # (J, 3) metres; offsets[0] is unused (root_pos places joint 0)
    end_site: NDArray[np.bool_] = field(default=None)  # type: ignore[arg-type]  # (J,); None: no end sites
    feet: tuple[Foot, ...] = ()  # empty, or four feet in FOOT_NAMES order
    name: str = ""

    def __post_init__(self) -> None:
        parents = np.asarray(self.parents, dtype=np.int32)
        offsets = np.asarray(self.offsets, dtype=np.float32)
        n = len(self.names)
        if n == 0:
            raise ValueError("A skeleton needs at least one joint")
        if parents.shape != (n,):
            raise ValueError(f"Expected `parents` to have shape ({n},), got {parents.shape}")
        if offsets.shape != (n, 3):
            raise ValueError(f"Expected `offsets` to have shape ({n}, 3), got {offsets.shape}")
        if not np.all(np.isfinite(offsets)):
            raise ValueError("`offsets` must be finite")
        if parents[0] != -1 or np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, n)):
            raise ValueError("`parents` must be topological: parents[0] == -1, 0 <= parents[j] < j")
        if len(set(self.names)) != n:
            raise ValueError("Joint names must be unique")
        end_site = (np.zeros(n, bool) if self.end_site is None
                    else np.asarray(self.end_site, dtype=bool))
        if end_site.shape != (n,):
            raise ValueError(f"Expected `end_site` to have shape ({n},), got {end_site.shape}")
        if self.feet and tuple(f.name for f in self.feet) != FOOT_NAMES:
            raise ValueError(f"Feet must be the four {FOOT_NAMES} in that order")
        for foot in self.feet:
            chain = foot.chain
            if not chain or chain[-1] != foot.end_effector:
                raise ValueError(f"Foot {foot.name}: its chain must end at its end effector")
            if any(parents[b] != a for a, b in zip(chain[:-1], chain[1:], strict=False)):
                raise ValueError(f"Foot {foot.name}: chain {chain} is not a parent-child path")
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "end_site", end_site)

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"No joint named {name!r} in skeleton {self.name!r}") from None

    @property
    def foot_joints(self) -> NDArray[np.int64]:
        """End-effector joint index of each foot, in FOOT_NAMES order, shape (4,)."""
        if not self.feet:
            raise ValueError(f"Skeleton {self.name!r} declares no feet")
        return np.array([f.end_effector for f in self.feet])

    def children(self, joint: int) -> list[int]:
        return [int(j) for j in np.flatnonzero(self.parents == joint)]

    def chain_to(self, end: int, stop: int) -> tuple[int, ...]:
        """Joint indices from ``stop`` down to ``end`` (``stop`` must be an ancestor)."""
        path = [end]
        while path[-1] != stop:
            parent = int(self.parents[path[-1]])
            if parent < 0:
                raise ValueError(f"{self.names[stop]} is not an ancestor of {self.names[end]}")
            path.append(parent)
        return tuple(reversed(path))

    def limb_chain(self, end: int) -> tuple[int, ...]:
        """The limb above an end effector: up to (excluding) the first joint with several children.

        For a dog's front paw that is shoulder..paw (the branch point is the upper spine); for a
        hind paw, thigh..paw (the branch point is the hips).
        """
        path = [end]
        while True:
            parent = int(self.parents[path[-1]])
            if parent < 0 or len(self.children(parent)) > 1:
                break
            path.append(parent)
        return tuple(reversed(path))

    def with_feet(self, end_effectors: Mapping[str, str]) -> Skeleton:
        """A copy with the four feet declared by end-effector joint name, e.g. {"LF": "LeftHand_end"}."""
        missing = [f for f in FOOT_NAMES if f not in end_effectors]
        if missing:
            raise ValueError(f"feet: missing {missing}; need all of {list(FOOT_NAMES)}")
        feet = []
        for foot in FOOT_NAMES:
            end = self.index(end_effectors[foot])
            feet.append(Foot(foot, end, self.limb_chain(end)))
        return Skeleton(self.names, self.parents, self.offsets, self.end_site, tuple(feet), self.name)

    def bone_lengths(self) -> NDArray[np.float32]:
        """Length of the bone from each joint's parent to it, (J,); 0 for the root."""
        lengths = np.linalg.norm(self.offsets, axis=-1)
        lengths[0] = 0.0
        return np.asarray(lengths, dtype=np.float32)

    def leg_length(self) -> float:
        """Mean length of the four limb chains (sum of bone lengths): the animal's size unit."""
        if not self.feet:
            raise ValueError(f"Skeleton {self.name!r} declares no feet")
        lengths = self.bone_lengths()
        return float(np.mean([lengths[list(f.chain[1:])].sum() for f in self.feet]))


# Name fragments by which common rigs mark fore and hind limbs (checked on the limb's root
# joint first: "LeftShoulder" is fore, "LeftUpLeg" is hind).
_FORE = ("shoulder", "clavicle", "scapula", "humerus", "arm", "hand", "fore", "front", "wrist")
_HIND = ("upleg", "thigh", "hip", "femur", "leg", "foot", "hind", "back", "ankle", "hock")
_SIDE_PREFIX = re.compile(r"^(?:([lr])[_.\-]|([LR])(?=[A-Z]))", re.IGNORECASE)


def _side(name: str) -> str | None:
    lower = name.lower()
    if "left" in lower:
        return "L"
    if "right" in lower:
        return "R"
    match = _SIDE_PREFIX.match(name)
    return (match.group(1) or match.group(2)).upper() if match else None


def _limb_kind(names: list[str]) -> str | None:
    """'F' or 'H' from the sided joint names of a path, limb root first."""
    for name in names:
        lower = name.lower()
        if any(k in lower for k in _FORE):
            return "F"
        if any(k in lower for k in _HIND):
            return "H"
    return None


def guess_feet(skeleton: Skeleton) -> dict[str, str]:
    """Guess the four feet of a rig from joint names (Left/Right; Shoulder/Arm vs UpLeg/Foot).

    Each foot is the deepest leaf under a limb of that side and kind. Raises a clear error when
    the names do not tell; callers then pass the four end-effector names explicitly.
    """
    best: dict[str, tuple[int, int]] = {}
    for leaf in range(skeleton.n_joints):
        if skeleton.children(leaf):
            continue
        path = [skeleton.names[j] for j in skeleton.chain_to(leaf, 0)]
        sided = [n for n in path if _side(n)]
        kind = _limb_kind(sided)
        if not sided or kind is None:
            continue
        foot = f"{_side(sided[0])}{kind}"
        if foot not in best or len(path) > best[foot][0]:
            best[foot] = (len(path), leaf)
    missing = [f for f in FOOT_NAMES if f not in best]
    if missing:
        raise ValueError(
            f"feet: cannot tell the {missing} foot joints from the joint names; "
            "pass the four end-effector joint names explicitly")
    return {f: skeleton.names[best[f][1]] for f in FOOT_NAMES}


def forward_kinematics(
    skeleton: Skeleton,
    root_pos: NDArray[np.floating],
    rotations: NDArray[np.floating],
    offsets: NDArray[np.floating] | None = None,
) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
    """World positions ``(..., J, 3)`` and rotations ``(..., J, 4)`` of every joint.

    ``root_pos (..., 3)`` and ``rotations (..., J, 4)`` may carry any leading axes (frames,
    characters). ``offsets`` overrides the skeleton's rest offsets and may itself carry leading
    axes (per-character scale, stretched limbs). Loops over joints only, in parent order.
    """
    rotations = np.asarray(rotations)
    root_pos = np.asarray(root_pos)
    J = skeleton.n_joints
    if rotations.shape[-2:] != (J, 4):
        raise ValueError(f"Expected `rotations` to have shape (..., {J}, 4), got {rotations.shape}")
    if root_pos.shape[-1:] != (3,):
        raise ValueError(f"Expected `root_pos` to have shape (..., 3), got {root_pos.shape}")
    offs = skeleton.offsets if offsets is None else np.asarray(offsets)
    lead = np.broadcast_shapes(rotations.shape[:-2], root_pos.shape[:-1], offs.shape[:-2])
    dtype = np.result_type(rotations.dtype, root_pos.dtype, np.float32)
    g_rot = np.empty((*lead, J, 4), dtype=dtype)
    g_pos = np.empty((*lead, J, 3), dtype=dtype)
    g_rot[..., 0, :] = rotations[..., 0, :]
    g_pos[..., 0, :] = root_pos
    parents = skeleton.parents
    for j in range(1, J):
        p = parents[j]
        g_pos[..., j, :] = g_pos[..., p, :] + quat.rotate(g_rot[..., p, :], offs[..., j, :])
        g_rot[..., j, :] = quat.mul(g_rot[..., p, :], rotations[..., j, :])
    return g_pos, g_rot
