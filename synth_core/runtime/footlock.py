"""Foot lock (beyond the paper; after Kovar et al. 2002): planted feet stay where they land.

Blending clips, bending them along curved paths and scaling them all make a planted foot drift.
A last pass over the synthesized motion, vectorized over (characters, frames):

1. Each plant (a run of planted frames of one foot) gets one world position: the foot's average
   over the plant.
2. A swinging foot follows its own path plus a correction eased (smoothstep) from the one its
   last plant needed at lift-off to the one its next plant needs at touchdown -- over the
   ground only, so swing heights are the clip's.
3. Where a target would straighten a leg beyond 98% of its reach, the root sinks just enough
   (at most ``MAX_SINK`` of the leg length), eased in and out over ``EASE_FRAMES``.
4. Limb IK (:mod:`synth_core.build.ik`) puts each foot on its target.

Scaled characters are solved in their own unit: a character of scale h is the library skeleton
with every length times h, so dividing its world positions by h gives the library's geometry.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from synth_core import UP_AXIS
from synth_core.build import ik
from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton, forward_kinematics
from synth_core.runtime.terrain import Grounding, ground_targets, untilt

Floats = NDArray[np.float64]
REACH = 0.98  # of a leg's full reach, at most
MAX_SINK = 0.05  # of the leg length, the most the root is lowered
# ... on a terrain: a foot planted a stride downhill of its hip is further from it than on the
# flat (at 30%, 7% of the leg for a foot half a leg ahead), and a body lowers rather than a leg
# stretches (issue 33).
TERRAIN_MAX_SINK = 0.2
EASE_FRAMES = 9
# Frames either side of a frame that its eased sink reads: the running max's half width plus the
# Gaussian's radius (ease_sink: sigma EASE_FRAMES / 6, truncated at 4 sigma).
PAD = EASE_FRAMES // 2 + int(4.0 * EASE_FRAMES / 6 + 0.5)


def plant_targets(feet: NDArray[np.floating], contacts: NDArray[np.bool_]) -> Floats:
    """Foot targets ``(C, T, 4, 3)`` from positions ``feet (C, T, 4, 3)`` and ``contacts (C, T, 4)``."""
    C, T, n_feet = contacts.shape
    R = C * n_feet
    con = np.ascontiguousarray(contacts.transpose(0, 2, 1)).reshape(R * T)
    pos = np.ascontiguousarray(np.asarray(feet, np.float64).transpose(0, 2, 1, 3)).reshape(R * T, 3)
    t = np.tile(np.arange(T), R)
    row_first = t == 0
    row_last = t == T - 1
    prev = np.concatenate([[False], con[:-1]]) & ~row_first
    nxt = np.concatenate([con[1:], [False]]) & ~row_last
    starts = np.flatnonzero(con & ~prev)
    ends = np.flatnonzero(con & ~nxt)
    targets = pos.copy()
    if len(starts) == 0:
        return np.asarray(targets.reshape(C, n_feet, T, 3).transpose(0, 2, 1, 3))
    run = np.cumsum(con & ~prev) - 1  # the last plant started at or before each frame
    planted = np.flatnonzero(con)
    counts = np.bincount(run[planted], minlength=len(starts))
    average = np.stack([np.bincount(run[planted], weights=pos[planted, d], minlength=len(starts))
                        for d in range(3)], axis=-1) / counts[:, None]
    targets[planted] = average[run[planted]]
    # Swings: eased from the last plant's lift-off correction to the next one's touchdown one.
    swing = np.flatnonzero(~con)
    row = swing // T
    run_row = starts // T
    before = run[swing]
    after = before + 1
    has_before = (before >= 0) & (run_row[np.maximum(before, 0)] == row)
    has_after = (after < len(starts)) & (run_row[np.minimum(after, len(starts) - 1)] == row)
    before, after = np.maximum(before, 0), np.minimum(after, len(starts) - 1)
    lift = average[before] - pos[ends[before]]
    touch = average[after] - pos[starts[after]]
    lift[:, UP_AXIS] = touch[:, UP_AXIS] = 0.0
    span = np.maximum(starts[after] - ends[before], 1)
    u = np.clip((swing - ends[before]) / span, 0.0, 1.0)
    u = u * u * (3 - 2 * u)
    u = np.where(has_before & has_after, u, np.where(has_after, 1.0, 0.0))
    correction = (1 - u)[:, None] * lift + u[:, None] * touch
    correction[~(has_before | has_after)] = 0.0
    targets[swing] += correction
    return np.asarray(targets.reshape(C, n_feet, T, 3).transpose(0, 2, 1, 3))


def ease_sink(sink: Floats, limit: float) -> Floats:
    """A per-frame sink (C, T) spread in time (running max, then Gaussian) and bounded."""
    spread = maximum_filter1d(np.minimum(sink, limit), EASE_FRAMES, axis=-1, mode="nearest")
    return np.asarray(gaussian_filter1d(spread, EASE_FRAMES / 6, axis=-1, mode="nearest"))


def lock_feet(skeleton: Skeleton, root_pos: NDArray[np.floating], rotations: NDArray[np.floating],
              contacts: NDArray[np.bool_], scales: NDArray[np.floating],
              ground: NDArray[np.floating] | None = None, rigs: tuple[ik.LimbRig, ...] | None = None,
              bends: NDArray[np.floating] | None = None,
              terrain: Grounding | None = None, lean: NDArray[np.floating] | None = None
              ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Root ``(C, T, 3)`` and local rotations ``(C, T, J, 4)`` with planted feet pinned.

    ``ground (C, T)``: the height planted feet stand at (default: as they are); ``bends (4, 3)``:
    the legs' bend axes (:func:`synth_core.build.ik.bend_axes`; default: over this motion).
    ``terrain``: the body already tilted by ``terrain.tilt`` and standing on ``ground``; the feet
    are planted on ``terrain.field`` (:mod:`synth_core.runtime.terrain`). ``lean (C, T, 4)``: the
    body already leant into its turn by these world rotations (under the tilt); plants are made
    from the feet as they hang unleaned, as on a terrain."""
    rigs = ik.limb_rigs(skeleton) if rigs is None else rigs
    h = np.asarray(scales, np.float64)[:, None, None]
    unit_root = np.asarray(root_pos, np.float64) / h
    pos, _ = forward_kinematics(skeleton, unit_root, rotations)
    feet = np.asarray(pos, np.float64)[..., skeleton.foot_joints, :]
    if terrain is not None and ground is not None:
        tilt = terrain.tilt if lean is None else np.asarray(quat.mul(terrain.tilt, lean), np.float64)
        feet = untilt(feet, unit_root, tilt)
        feet[..., UP_AXIS] -= (np.asarray(ground, np.float64) / h[..., 0])[..., None]
        targets = ground_targets(plant_targets(feet, contacts), contacts, terrain.field, h[:, 0, 0])
    else:
        if lean is not None:
            leans = np.asarray(lean, np.float64)
            leant = (leans[..., :3] != 0).any(axis=-1)  # (the rest as they are, bit for bit)
            feet = np.where(leant[..., None, None], untilt(feet, unit_root, leans), feet)
        targets = plant_targets(feet, contacts)
    if ground is not None and terrain is None:  # planted feet on the ground the path runs over
        floor = (np.asarray(ground, np.float64) / h[..., 0])[..., None]
        targets[..., UP_AXIS] = np.maximum(targets[..., UP_AXIS], floor)
    sink = ik.sink_to_reach(skeleton, unit_root, rotations, targets, np.full(4, REACH), rigs)
    most = (MAX_SINK if terrain is None else TERRAIN_MAX_SINK) * skeleton.leg_length()
    sink = ease_sink(np.asarray(sink, np.float64), most)
    unit_root[..., UP_AXIS] -= sink
    solved = ik.solve(skeleton, unit_root, rotations, targets, rigs, ground=None, bends=bends)
    return (unit_root * h).astype(np.float32), solved.rotations
