"""Planar leg model used to generate the built-in gaits (sagittal plane, angles from straight down).

Strategy for legs of more than two segments (stated for issue 3; the general 3D IK of the speed
maps is :mod:`synth_core.build.ik`): the girdle (scapula) angle, the flexion of the distal joint (carpus
in front, hock behind) and the digit angles (pastern, hoof or toe) are *prescribed* by the gait;
the two main joints (shoulder and elbow in front, hip and stifle behind) are *solved*
analytically as a two-link chain from the limb root to the fetlock, the second link being the
forearm (or gaskin) and cannon together at the prescribed distal flexion. The elbow is placed
behind the root-fetlock line and the stifle in front of it, as in the animals, so joints bend the
anatomically right way by construction.

Angle convention: a bone's angle is measured from straight down, positive when its lower end is
forward (+Z). A rotation about +X by theta changes a bone's angle by -theta.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core.motion.skeleton import Skeleton

Floats = NDArray[np.float64]


def bone_vector(angle: Floats, length: float | Floats) -> Floats:
    """(..., 2) sagittal vectors (z, y) of bones with the given angles from straight down."""
    return np.stack([length * np.sin(angle), -length * np.cos(angle)], axis=-1)


def angle_of(vec: Floats) -> Floats:
    """Angle from straight down of (..., 2) sagittal vectors (z, y)."""
    return np.arctan2(vec[..., 0], -vec[..., 1])


@dataclass(frozen=True)
class Limb:
    """One leg of a skeleton, by role. Indices are into ``chain`` (bone i runs chain[i] -> chain[i+1])."""

    foot: str
    chain: tuple[int, ...]
    lengths: Floats  # (B,) bone lengths
    rest_angles: Floats  # (B,) bone angles in the rest (standing) pose
    girdle: int | None  # the scapula bone, fore limbs only
    upper: int  # humerus / femur
    bend: float  # +1: middle joint (stifle) ahead of the root-fetlock line; -1: behind (elbow)
    flex_sign: float  # distal joint flexion folds the metapodial back (-1, carpus) or forward (+1, hock)

    @property
    def lower(self) -> int:
        return self.upper + 1

    @property
    def meta(self) -> int:
        return self.upper + 2

    @property
    def digits(self) -> range:
        return range(self.upper + 3, len(self.lengths))


def limbs_of(skeleton: Skeleton) -> list[Limb]:
    """The four legs of a built-in skeleton: fore limbs carry a girdle bone, hind limbs do not."""
    limbs = []
    for foot in skeleton.feet:
        chain = foot.chain
        bones = skeleton.offsets[list(chain[1:])].astype(np.float64)  # bone i = offset of chain[i+1]
        lengths = np.linalg.norm(bones[:, [1, 2]], axis=-1)
        rest = np.arctan2(bones[:, 2], -bones[:, 1])
        fore = foot.name[1] == "F"
        upper = 1 if fore else 0
        if len(lengths) < upper + 4:
            raise ValueError(f"{foot.name}: a leg needs girdle/upper, lower, metapodial and a digit bone")
        limbs.append(Limb(foot.name, chain, lengths, rest, girdle=0 if fore else None, upper=upper,
                          bend=-1.0 if fore else 1.0, flex_sign=-1.0 if fore else 1.0))
    return limbs


def effective_link(limb: Limb, distal_flex: Floats) -> tuple[Floats, Floats]:
    """Length and angle offset of lower + metapodial as one link, at the given distal flexion.

    Returns (length (...), delta (...)) where delta = angle(link) - angle(lower bone).
    """
    rel = limb.rest_angles[limb.meta] - limb.rest_angles[limb.lower] + limb.flex_sign * distal_flex
    link = bone_vector(np.zeros_like(rel), limb.lengths[limb.lower]) \
        + bone_vector(rel, limb.lengths[limb.meta])
    return np.linalg.norm(link, axis=-1), angle_of(link)


@dataclass(frozen=True)
class LegSolution:
    angles: Floats  # (F, B) world sagittal angle of every bone
    miss: Floats  # (F,) distance (m) by which the foot misses its target (0 when reachable)
    distal_flex: Floats  # (F,) the distal joint's flexion used (the prescribed one, opened for reach)
    extension: Floats  # (F,) distance to the fetlock over the two main links' reach (1: straight)


REACH_MARGIN = 0.97  # keep the elbow / stifle bent: use at most 97% of the two-link reach
MIN_DISTAL_FLEX = {1.0: np.radians(-30.0), -1.0: 0.0}  # the hock may open 30 deg; the carpus no further


def _girdle_for_reach(root: Floats, fetlock: Floats, girdle: Floats, length: float,
                      reach: Floats) -> Floats:
    """The girdle angle nearest the prescribed one whose lower end is within ``reach`` of the fetlock.

    The shoulder joint moves on a circle about the scapula top; where the prescribed angle leaves
    it too far from the fetlock, take the nearest intersection of that circle with the circle of
    radius ``reach`` about the fetlock (or point straight at the fetlock when they do not meet).
    """
    shoulder = root + bone_vector(girdle, length)
    too_far = np.linalg.norm(fetlock - shoulder, axis=-1) > reach
    to_fetlock = fetlock - root
    dist = np.linalg.norm(to_fetlock, axis=-1)
    base = angle_of(to_fetlock)
    cos_g = np.clip((length**2 + dist**2 - reach**2) / (2 * length * np.maximum(dist, 1e-9)), -1.0, 1.0)
    gamma = np.arccos(cos_g)
    candidates = np.stack([base - gamma, base + gamma], axis=-1)
    pick = np.abs(candidates - girdle[:, None]).argmin(axis=-1)[:, None]
    nearest = np.take_along_axis(candidates, pick, axis=-1)[:, 0]
    return np.where(too_far, nearest, girdle)


def _distal_flex_for_reach(limb: Limb, distal_flex: Floats, needed: Floats) -> Floats:
    """Open the distal joint (hock) where the lower link is shorter than ``needed``, within limits."""
    a, b = limb.lengths[limb.lower], limb.lengths[limb.meta]
    needed = np.clip(needed, abs(a - b) + 1e-6, a + b - 1e-6)
    rel_needed = np.pi - np.arccos(np.clip((a * a + b * b - needed**2) / (2 * a * b), -1.0, 1.0))
    rel_rest = limb.rest_angles[limb.meta] - limb.rest_angles[limb.lower]
    flex_needed = limb.flex_sign * (np.sign(rel_rest) * rel_needed - rel_rest)
    current, _ = effective_link(limb, distal_flex)
    # Never below the joint's limit, but never flexed further than asked either.
    opened = np.maximum(np.minimum(distal_flex, flex_needed),
                        np.minimum(MIN_DISTAL_FLEX[limb.flex_sign], distal_flex))
    return np.where(current < needed, opened, distal_flex)


def solve_leg(limb: Limb, root: Floats, foot: Floats, girdle_angle: Floats | None,
              distal_flex: Floats, digit_angles: Floats,
              adapt: Floats | None = None) -> LegSolution:
    """Bone angles putting the end effector at ``foot``.

    ``root (F, 2)``: the limb root joint (scapula top, hip joint) in (z, y); ``foot (F, 2)``;
    ``girdle_angle (F,)`` for fore limbs (preferred; rotated further where the foot needs the
    reach); ``distal_flex (F,)`` radians (preferred; the hock opens where needed); ``digit_angles
    (F, D)`` world angles of the digit bones, top first. ``adapt (F,)`` in [0, 1]: how far the
    girdle and distal joint give way for reach (1 in stance, where the foot must be on its plant;
    fading out in swing, where the planned toe path is only a guide; a weight, not a switch, so
    nothing pops). Default: 1 everywhere.
    """
    adapt = np.ones(len(root)) if adapt is None else adapt
    F = len(root)
    angles = np.zeros((F, len(limb.lengths)))
    digits = list(limb.digits)
    angles[:, digits] = digit_angles
    fetlock = foot - bone_vector(digit_angles, limb.lengths[digits]).sum(axis=1)
    l1 = limb.lengths[limb.upper]
    start = root
    if limb.girdle is not None:
        if girdle_angle is None:
            raise ValueError(f"{limb.foot}: a fore limb needs its girdle angle")
        l2, _ = effective_link(limb, distal_flex)
        reached = _girdle_for_reach(root, fetlock, girdle_angle, limb.lengths[limb.girdle],
                                    REACH_MARGIN * (l1 + l2))
        girdle = girdle_angle + adapt * (reached - girdle_angle)
        angles[:, limb.girdle] = girdle
        start = root + bone_vector(girdle, limb.lengths[limb.girdle])
    d = np.linalg.norm(fetlock - start, axis=-1)
    distal_flex = distal_flex + adapt * (_distal_flex_for_reach(limb, distal_flex, d / REACH_MARGIN - l1)
                                         - distal_flex)
    l2, delta = effective_link(limb, distal_flex)
    to_target = fetlock - start
    reach = np.clip(d, np.abs(l1 - l2) + 1e-9, l1 + l2 - 1e-9)
    cos_a = np.clip((l1**2 + reach**2 - l2**2) / (2 * l1 * reach), -1.0, 1.0)
    upper = angle_of(to_target) + limb.bend * np.arccos(cos_a)
    knee = start + bone_vector(upper, l1)
    link_angle = angle_of(fetlock - knee)
    angles[:, limb.upper] = upper
    angles[:, limb.lower] = link_angle - delta
    angles[:, limb.meta] = angles[:, limb.lower] + (limb.rest_angles[limb.meta] - limb.rest_angles[limb.lower]
                                                    + limb.flex_sign * distal_flex)
    reached = start + bone_vector(angles[:, limb.upper:], limb.lengths[limb.upper:]).sum(axis=1)
    return LegSolution(angles, np.linalg.norm(reached - foot, axis=-1), distal_flex, d / (l1 + l2))
