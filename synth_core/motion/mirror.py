"""Left/right mirror images of poses: the same motion on the other lead (issue 28).

A herd started together leaves standing by one transition with the same foot first, and
transitions play by distance, so it steps as one; real herds canter and gallop on both leads.
A pose's mirror image -- the body reflected about its sagittal plane -- is as sound a pose as the
original for a symmetric skeleton, and gives the other lead (a canter's leading fore on the
other side) with every foot's timing kept.

For a skeleton whose joints come in left/right pairs (by name) with reflected rest offsets, and
whose joints' local frames are the rest frame (BVH-style: no joint orients), reflecting a pose
about the body's sagittal plane (normal ``n``, the lateral axis) is, per joint, a change of
joint -- each to its partner, midline joints to themselves -- and of rotation: ``M R M`` with
``M = I - 2 n n^T``, a rotation about the reflected axis ``-M a`` by the same angle, i.e. the
quaternion ``(2 n (n . v) - v, w)``. The root turns the body into the world: its mirror is
``M_w R M``, ``M_w`` the world's reflection about the plane the clip travels in (the bank's
canonical clips face +Z, so its normal is +X).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton

Floats = NDArray[np.float64]
FOOT_SWAP = np.array([1, 0, 3, 2])  # LF, RF, LH, RH -> the partner foot's column
# Name marks of the two sides in common rigs, tried in this order ("L_Femur", "LeftUpLeg", ...).
SIDES = (("Left", "Right"), ("left", "right"), ("LEFT", "RIGHT"), ("L_", "R_"), ("l_", "r_"),
         ("_L", "_R"), ("_l", "_r"), (".L", ".R"), (".l", ".r"))
# How far a joint's rest offset may be from its partner's reflected, over the mean leg length:
# 1 % (a horse: 1.4 cm) -- a rig built symmetric is so to the float; a captured skeleton whose
# sides differ by more would not put a mirrored foot where the original's partner was.
SYMMETRY_TOLERANCE = 0.01


@dataclass(frozen=True, eq=False)
class Mirror:
    """How a skeleton's poses are mirrored: each joint's partner and the body's lateral axis."""

    partner: NDArray[np.int64]  # (J,) the joint on the other side (midline joints: themselves)
    normal: Floats  # (3,) the body's lateral axis in the rest frame (left minus right, unit)


def _partner_name(name: str, names: set[str]) -> str | None:
    """The joint named as ``name`` on the other side, or None (a midline joint: no side mark)."""
    for left, right in SIDES:
        for a, b in ((left, right), (right, left)):
            if a in name:
                other = name.replace(a, b)
                if other in names:
                    return other
    return None


def skeleton_mirror(skeleton: Skeleton) -> Mirror | None:
    """The skeleton's :class:`Mirror`, or None where its poses have no sound mirror image: no
    left/right pairing by name, feet not paired LF-RF and LH-RH, or sides whose rest offsets are
    not each other's reflection (within SYMMETRY_TOLERANCE of the leg length), midline joints
    off the plane."""
    if not skeleton.feet:
        return None
    names = set(skeleton.names)
    partner = np.arange(skeleton.n_joints)
    for j, name in enumerate(skeleton.names):
        other = _partner_name(name, names)
        if other is not None:
            partner[j] = skeleton.index(other)
    feet = skeleton.foot_joints
    if (partner[partner] != np.arange(len(partner))).any() or (partner[feet] != feet[FOOT_SWAP]).any():
        return None
    offsets = np.asarray(skeleton.offsets, np.float64).copy()
    offsets[0] = 0.0  # the root's is unused (root_pos places joint 0)
    rest = _rest_positions(skeleton, offsets)
    lateral = (rest[feet[0]] - rest[feet[1]]) + (rest[feet[2]] - rest[feet[3]])
    if np.linalg.norm(lateral) < 1e-9:
        return None
    normal = lateral / np.linalg.norm(lateral)
    reflected = offsets - 2.0 * (offsets @ normal)[:, None] * normal
    if np.abs(reflected - offsets[partner]).max() > SYMMETRY_TOLERANCE * skeleton.leg_length():
        return None
    return Mirror(partner.astype(np.int64), normal)


def _rest_positions(skeleton: Skeleton, offsets: Floats) -> Floats:
    """Joint positions of the rest pose (every rotation the identity), the root at the origin."""
    rest = np.zeros_like(offsets)
    for j in range(1, skeleton.n_joints):
        rest[j] = rest[skeleton.parents[j]] + offsets[j]
    return rest


def reflect(q: NDArray[np.floating], normal: Floats) -> Floats:
    """``M R M`` of rotations ``q (..., 4)``, ``M`` the reflection about the plane of ``normal``."""
    v = np.asarray(q[..., :3], np.float64)
    v = 2.0 * (v @ normal)[..., None] * normal - v
    return np.concatenate([v, np.asarray(q[..., 3:], np.float64)], axis=-1)


CANONICAL_SIDE = np.array([1.0, 0.0, 0.0])  # the bank's clips travel along +Z, Y up: their side is X


def mirror_poses(mirror: Mirror, poses: NDArray[np.floating],
                 world_normal: Floats = CANONICAL_SIDE) -> Floats:
    """The mirror images of local rotations ``poses (K, J, 4)``: each joint takes its partner's
    rotation reflected; the root's is reflected between the body's plane and the world's
    (``world_normal``: the plane the clips travel in)."""
    out = reflect(np.asarray(poses)[:, mirror.partner], mirror.normal)
    m_world = np.eye(3) - 2.0 * np.outer(world_normal, world_normal)
    m_body = np.eye(3) - 2.0 * np.outer(mirror.normal, mirror.normal)
    turn = quat.from_matrix(m_world @ m_body)  # two reflections: a rotation
    out[:, 0] = quat.mul(turn, out[:, 0])
    return np.asarray(out)
