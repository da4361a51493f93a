"""Built-in skeletons: a horse (withers 1.6 m) and a dog (hip height 0.46 m).

Conventions beyond the glossary in :mod:`synth_core`: the animals face **+Z**, their left is
**+X** (glTF's convention, Y up, right-handed). The rest pose *is* the square standing pose (every
local rotation the identity), so IK and gait generation work with deviations from standing.
Joints are declared in depth-first preorder, so a BVH round trip keeps their order. Each limb is
built from the ground up: segment lengths and standing angles in the sagittal plane.

Sources (numbers rounded; where a value is our estimate it says so):

Horse, a 1.6 m (15.3 hh) warmblood:
- Withers height 1.60 m, body length (point of shoulder to point of buttock) about equal to it:
  the usual "square" riding horse (Back & Clayton, *Equine Locomotion*, 2nd ed., 2013, ch. 1).
- Limb segment lengths, scaled to that height from the segment data of Dutch Warmbloods in
  Buchner, Savelberg, Schamhardt & Barneveld 1997, "Inertial properties of Dutch Warmblood
  horses", J. Biomech. 30(6):653-658, and the 38 horses of Nauwelaerts & Clayton (2011, J. Anat.
  219:391-400, "Inertial properties of equine limb segments"): scapula ~0.40 m, humerus ~0.30,
  radius (forearm) ~0.42, fore cannon ~0.26, femur ~0.42, tibia ~0.42, hind cannon ~0.30,
  pastern (P1+P2) ~0.16, hoof (coffin joint to ground) ~0.09 m. The hind cannon is longer than
  the fore cannon and the forearm longer than the cannon, as in every horse; exact values are our
  rounding.
- Standing joint angles (our estimates from standard conformation texts): scapula ~40 deg from
  vertical (a "45-degree shoulder"), pastern and hoof axis ~55 deg from the ground (35 deg from
  vertical) in front and behind, forearm and fore cannon vertical, stifle ahead of the hip and the
  hock behind the stifle (femur ~35 deg, tibia ~40 deg from vertical).
- Head ~0.60 m, neck ~0.75 m (our estimates for a 1.6 m horse).

Dog: the proportions of the real dog of the MANN data set (Zhang, Starke, Komura & Saito 2018,
"Mode-Adaptive Neural Networks for Quadruped Motion Control", SIGGRAPH; hierarchy in
``../shared/mocap/mann_dog/SOURCE.md``): hips 0.46 m high when standing, spine 0.19 + 0.225 m,
neck 0.14 m, head 0.17 m, fore limb 0.08 (scapula) + 0.152 (humerus) + 0.178 (radius) + 0.072 m
(paw), hind limb 0.16 (femur) + 0.18 (tibia) + 0.108 m (metatarsus and paw), tail 0.24 m. Our
joint names are our own; we split each MANN paw into a metapodial and a toe segment (same total)
so the toe can roll off the ground.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from synth_core.motion.skeleton import Skeleton


@dataclass(frozen=True)
class Segment:
    """A limb bone in the sagittal plane: length (m) and standing angle from straight down.

    Positive angles put the bone's lower end forward (+Z) of its upper end.
    """

    joint: str  # the joint at the bone's upper end, which rotates this bone
    length: float
    angle_deg: float


class _Builder:
    """Joints in standing world positions; offsets are their differences to the parent."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.parents: list[int] = []
        self.positions: list[np.ndarray] = []
        self.end_site: list[bool] = []

    def add(self, name: str, parent: int, position: Sequence[float], end: bool = False) -> int:
        self.names.append(name)
        self.parents.append(parent)
        self.positions.append(np.asarray(position, dtype=np.float64))
        self.end_site.append(end)
        return len(self.names) - 1

    def chain(self, parent: int, points: Sequence[tuple[str, Sequence[float]]], end: str) -> int:
        """Joints at ``points`` each the child of the one before; the last becomes end site ``end``."""
        for name, point in points[:-1]:
            parent = self.add(name, parent, point)
        return self.add(end, parent, points[-1][1], end=True)

    def limb(self, parent: int, side_x: float, foot_z: float, segments: Sequence[Segment],
             end: str) -> int:
        """A leg standing on the ground: built up from the foot, added top-down."""
        z, y = foot_z, 0.0
        points: list[tuple[str, Sequence[float]]] = [(end, (side_x, 0.0, foot_z))]
        for seg in reversed(segments):
            a = np.radians(seg.angle_deg)
            z, y = z - seg.length * np.sin(a), y + seg.length * np.cos(a)
            points.append((seg.joint, (side_x, y, z)))
        return self.chain(parent, list(reversed(points)), end)

    def legs(self, parent: int, half_width: float, foot_z: float, segments: Sequence[Segment],
             end_bone: str) -> None:
        """A left (+X) and a right (-X) leg; joints prefixed L_ / R_, end sites <L|R>_<end_bone>_end."""
        for side, x in (("L", 1.0), ("R", -1.0)):
            self.limb(parent, x * half_width, foot_z,
                      [Segment(f"{side}_{s.joint}", s.length, s.angle_deg) for s in segments],
                      f"{side}_{end_bone}_end")

    def build(self, name: str) -> Skeleton:
        pos = np.stack(self.positions)
        parents = np.array(self.parents)
        offsets = pos - pos[np.maximum(parents, 0)]
        offsets[0] = 0.0
        return Skeleton(tuple(self.names), parents, offsets.astype(np.float32),
                        np.array(self.end_site), name=name)

    def position(self, index: int) -> np.ndarray:
        return self.positions[index]


# --- horse -----------------------------------------------------------------------------------

HORSE_WITHERS_M = 1.60

HORSE_FORE = (
    Segment("Scapula", 0.40, 40.0),
    Segment("Humerus", 0.30, -50.0),
    Segment("Radius", 0.42, 0.0),
    Segment("Cannon", 0.26, 0.0),
    Segment("Pastern", 0.16, 35.0),
    Segment("Hoof", 0.095, 18.0),  # coffin joint to the ground contact under the toe quarter
)
HORSE_HIND = (
    Segment("Femur", 0.42, 35.0),
    Segment("Tibia", 0.42, -40.0),
    Segment("HindCannon", 0.30, 3.0),
    Segment("HindPastern", 0.16, 35.0),
    Segment("HindHoof", 0.095, 18.0),
)
HORSE_FORE_FOOT_Z = 1.20  # front hoof contacts, metres ahead of the pelvis (lumbosacral joint)
HORSE_HIND_FOOT_Z = -0.17
HORSE_HALF_WIDTH = (0.13, 0.12)  # fore, hind: hooves under the body, a hand's width inside the body


def horse_skeleton() -> Skeleton:
    b = _Builder()
    pelvis = b.add("Pelvis", -1, (0.0, 1.45, 0.0))  # lumbosacral joint
    spine1 = b.add("Spine1", pelvis, (0.0, 1.47, 0.45))  # thoracolumbar junction
    spine2 = b.add("Spine2", spine1, (0.0, 1.43, 0.85))  # mid thorax
    spine3 = b.add("Spine3", spine2, (0.0, 1.38, 1.12))  # cranial thorax, under the withers
    # The withers: tip of the T5 spinous process. BVH End Sites are unnamed, so end sites are
    # named <parent>_end throughout, which is what a BVH reader calls them.
    b.add("Spine3_end", spine3, (0.0, HORSE_WITHERS_M, 1.05), end=True)
    b.chain(spine3, [("Neck1", (0.0, 1.30, 1.35)), ("Neck2", (0.0, 1.48, 1.58)),
                     ("Neck3", (0.0, 1.68, 1.78)), ("Head", (0.0, 1.80, 1.90)),
                     ("Head_end", (0.0, 1.38, 2.33))], "Head_end")
    b.legs(spine3, HORSE_HALF_WIDTH[0], HORSE_FORE_FOOT_Z, HORSE_FORE, "Hoof")
    b.legs(pelvis, HORSE_HALF_WIDTH[1], HORSE_HIND_FOOT_Z, HORSE_HIND, "HindHoof")
    b.chain(pelvis, [("Tail1", (0.0, 1.44, -0.45)), ("Tail2", (0.0, 1.34, -0.60)),
                     ("Tail3", (0.0, 1.19, -0.72)), ("Tail3_end", (0.0, 1.01, -0.80))], "Tail3_end")
    return b.build("horse").with_feet({"LF": "L_Hoof_end", "RF": "R_Hoof_end",
                                       "LH": "L_HindHoof_end", "RH": "R_HindHoof_end"})


# --- dog -------------------------------------------------------------------------------------

DOG_HIP_HEIGHT_M = 0.46

DOG_FORE = (
    Segment("Scapula", 0.080, 35.0),
    Segment("Humerus", 0.152, -40.0),
    Segment("Radius", 0.178, 0.0),
    Segment("Metacarpus", 0.055, 12.0),
    Segment("FrontToe", 0.017, 45.0),
)
DOG_HIND = (
    Segment("Femur", 0.160, 30.0),
    Segment("Tibia", 0.180, -35.0),
    Segment("Metatarsus", 0.090, 8.0),
    Segment("HindToe", 0.018, 40.0),
)
# Paw placement and heights checked against the MANN dog standing (D1_ex01_KAN01_001, frames
# 20-140): fore paws ~0.37 m ahead of the hips, hind paws ~0.07 m behind, hind stance narrower.
DOG_FORE_FOOT_Z = 0.37
DOG_HIND_FOOT_Z = -0.07
DOG_HALF_WIDTH = (0.055, 0.04)


def dog_skeleton() -> Skeleton:
    b = _Builder()
    pelvis = b.add("Pelvis", -1, (0.0, DOG_HIP_HEIGHT_M, 0.0))
    spine1 = b.add("Spine1", pelvis, (0.0, 0.47, 0.19))
    spine2 = b.add("Spine2", spine1, (0.0, 0.46, 0.30))
    b.chain(spine2, [("Neck1", (0.0, 0.47, 0.38)), ("Neck2", (0.0, 0.52, 0.42)),
                     ("Head", (0.0, 0.57, 0.46)), ("Head_end", (0.0, 0.53, 0.62))], "Head_end")
    b.legs(spine2, DOG_HALF_WIDTH[0], DOG_FORE_FOOT_Z, DOG_FORE, "FrontToe")
    b.legs(pelvis, DOG_HALF_WIDTH[1], DOG_HIND_FOOT_Z, DOG_HIND, "HindToe")
    b.chain(pelvis, [("Tail1", (0.0, 0.45, -0.07)), ("Tail2", (0.0, 0.42, -0.15)),
                     ("Tail3", (0.0, 0.37, -0.22)), ("Tail3_end", (0.0, 0.31, -0.28))], "Tail3_end")
    return b.build("dog").with_feet({"LF": "L_FrontToe_end", "RF": "R_FrontToe_end",
                                     "LH": "L_HindToe_end", "RH": "R_HindToe_end"})


BUILTIN_ANIMALS: dict[str, Callable[[], Skeleton]] = {"horse": horse_skeleton, "dog": dog_skeleton}


def build_skeleton(animal: str) -> Skeleton:
    if animal not in BUILTIN_ANIMALS:
        raise ValueError(f"animal: expected one of {sorted(BUILTIN_ANIMALS)}, got {animal!r}")
    return BUILTIN_ANIMALS[animal]()
