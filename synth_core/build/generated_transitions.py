"""A transition the data lacks (:mod:`synth_core.build.manifest`): the two gaits' speed-map clips at a
speed both can do, cross-faded over a stride, the second time-shifted so its footfalls carry on
from the first's, and the feet pinned to their plants by IK (:func:`hold_plants`, which given
mocap transitions go through too)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from synth_core import UP_AXIS
from synth_core.build import ik
from synth_core.build.speed_map import (
    LEAST_DOWN,
    SpeedMap,
    cycle_displacement,
    foot_targets,
    held_feet,
    reach_limit,
    sink_for_reach,
)
from synth_core.build.straight_crossings import solve_eased
from synth_core.motion import contacts as C
from synth_core.motion import quat
from synth_core.motion.clip import Motion

Floats = NDArray[np.float64]


def _heading(motion: Motion) -> float:
    travel = motion.root_pos[-1] - motion.root_pos[0]
    return float(np.arctan2(travel[0], travel[2])) if np.hypot(travel[0], travel[2]) > 1e-6 else 0.0


def _turned(motion: Motion, yaw: float, start: np.ndarray) -> Motion:
    """The motion turned by ``yaw`` about +Y around its first root position, moved over ``start``
    on the ground: its root keeps its own heights (moved to ``start``'s height too, a transition's
    second clip stood every paw as far up or down as the two roots' heights differed at the
    switch: the real dog's generated trot2canter 15 mm over the canter's soles)."""
    q = quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), yaw)
    start = np.array(start, np.float64)
    start[UP_AXIS] = motion.root_pos[0, UP_AXIS]
    root = quat.rotate(q, motion.root_pos - motion.root_pos[0]) + start
    rotations = motion.rotations.copy()
    rotations[:, 0] = quat.mul(q, rotations[:, 0])
    return Motion(motion.skeleton, root.astype(np.float32), rotations, motion.fps, motion.contacts,
                  motion.name, motion.gait)


def _loops(clip: Motion, times: int) -> Motion:
    advance = cycle_displacement(clip.root_pos)
    root = np.concatenate([clip.root_pos + k * advance for k in range(times)])
    return Motion(clip.skeleton, root, np.tile(clip.rotations, (times, 1, 1)), clip.fps,
                  np.tile(clip.contacts, (times, 1)), clip.name, clip.gait)


def _nearest(speed_map: SpeedMap, speed: float) -> Motion:
    return speed_map.clip(int(np.abs(speed_map.speeds - speed).argmin()))


def generate_transition(a: SpeedMap | None, b: SpeedMap | None, idle: Motion, name: str) -> Motion:
    """A transition the data lacks: a's clip cross-faded into b's at a speed both can do."""
    if a is not None and b is not None:
        low = max(a.speeds[0], b.speeds[0])
        high = min(a.speeds[-1], b.speeds[-1])
        speed = 0.5 * (low + high) if low <= high else 0.5 * (a.speeds[-1] + b.speeds[0])
        first, second = _loops(_nearest(a, speed), 2), _loops(_nearest(b, speed), 2)
    elif a is not None:  # gait -> static: slow to the slowest clip, then stand
        first, second = _loops(a.clip(0), 2), idle
    elif b is not None:  # static -> gait
        first, second = idle, _loops(b.clip(0), 2)
    else:
        raise ValueError(f"{name}: neither side has clips")
    second = _turned(second, _heading(first) - _heading(second) if second.speed_mps() > 0.01 else 0.0,
                     first.root_pos[-1])
    return _crossfade(first, second, name)


def _best_shift(first: NDArray[np.bool_], second: NDArray[np.bool_], W: int, strides: int) -> int:
    """The cyclic shift of ``second`` whose footfalls carry on best from ``first``'s.

    Scored on the contacts the blend will have (first's, then second's from the blend's middle):
    first by how many frames steps come too soon (a doubled step: shorter than 0.6 of the shorter
    stride) or too late (a skipped one: longer than 1.5 of the longer stride), then by how well
    the two agree over the blend. Between gaits of different footfall (a trot's diagonal pairs,
    a canter's lead) one quick step may be unavoidable; this makes it the least quick.
    """
    Fa, Fb = len(first), len(second)
    stride_a, stride_b = Fa / strides, Fb / strides
    cut = Fa - W // 2  # where the blend's contacts switch over
    best: tuple[float, int, int] | None = None
    for s in range(Fb):  # offline, a few dozen candidates
        rolled = np.roll(second, -s, axis=0)
        played = np.concatenate([first[:cut], rolled[W - W // 2:]])
        gaps = np.concatenate([np.diff(downs) for downs in C.touchdowns(played)])
        short, long = 0.6 * min(stride_a, stride_b), 1.5 * max(stride_a, stride_b)
        odd = np.maximum(short - gaps, 0) + np.maximum(gaps - long, 0)
        score = (float(odd.sum()), -int((rolled[:W] == first[-W:]).sum()), s)
        best = score if best is None or score < best else best
    assert best is not None
    return best[2]


REACH_EASE_FRAMES = 9  # a transition's sink eases in and out over this many frames (as the foot lock's)
MAX_SINK = 0.15  # of the leg length, the most a transition's root is lowered: a plant joined over
# a blend's switch lies between the two clips' footprints, and reaching it crouched the real
# dog's generated canter2gallop 15 cm (a third of its leg) for 8 frames
SWITCH_GAP = 2  # frames: a gap this short where a blend switches contacts joins the plants


def _crossfade(first: Motion, second: Motion, name: str, strides: int = 2) -> Motion:
    """first, then second, blended over the frames where they overlap; feet pinned by IK.

    Both hold ``strides`` strides (a still clip: any length). ``second`` is time-shifted
    (cyclically, by up to its own length) so that footfalls carry on across the blend instead of
    doubling or skipping a step (:func:`_best_shift`).
    """
    Fa, Fb = first.n_frames, second.n_frames
    W = min(Fa, Fb) // 2
    s = _best_shift(first.contacts, second.contacts, W, strides)
    rot_b = np.roll(second.rotations, -s, axis=0)
    con_b = np.roll(second.contacts, -s, axis=0)
    # Steps into each frame, the loop's own seam step included, then shifted: rolling positions
    # instead would put the whole loop's advance, backwards, into one step.
    seam = second.root_pos[-1:] - cycle_displacement(second.root_pos)
    step_b = np.roll(np.diff(second.root_pos, axis=0, prepend=seam), -s, axis=0)
    T = Fa + Fb - W
    w = np.zeros(T)
    w[Fa - W:Fa] = np.linspace(0.0, 1.0, W)
    w[Fa:] = 1.0
    w = w * w * (3 - 2 * w)
    rot_a = np.concatenate([first.rotations, np.repeat(first.rotations[-1:], Fb - W, axis=0)])
    rot_bb = np.concatenate([np.repeat(rot_b[:1], Fa - W, axis=0), rot_b])
    rotations = quat.slerp(rot_a, rot_bb, w[:, None])
    step_a = np.diff(first.root_pos, axis=0, prepend=first.root_pos[:1])
    step_a[0] = step_a[1]
    steps = (1 - w)[:, None] * np.concatenate([step_a, np.repeat(step_a[-1:], Fb - W, axis=0)]) \
        + w[:, None] * np.concatenate([np.repeat(step_b[:1], Fa - W, axis=0), step_b])
    root = first.root_pos[0] + np.cumsum(steps, axis=0) - steps[0]
    height_a = np.concatenate([first.root_pos[:, UP_AXIS], np.full(Fb - W, first.root_pos[-1, UP_AXIS])])
    height_b = np.concatenate([np.full(Fa - W, second.root_pos[0, UP_AXIS]),
                               np.roll(second.root_pos, -s, axis=0)[:, UP_AXIS]])
    heights = (1 - w) * height_a + w * height_b
    root[:, UP_AXIS] = heights
    contacts = np.where((w < 0.5)[:, None],
                        np.concatenate([first.contacts, np.repeat(first.contacts[-1:], Fb - W, axis=0)]),
                        np.concatenate([np.repeat(con_b[:1], Fa - W, axis=0), con_b]))
    # A foot planted in both clips around the switch but lifted for a frame or two there (one
    # plant ends just before the other starts) stands in one plant: two would be pinned apart,
    # and the foot would jump between them (11 cm in the real dog's canter2gallop).
    contacts = C.fill_gaps(contacts, SWITCH_GAP)
    return hold_plants(Motion(first.skeleton, root, rotations, first.fps, contacts, name, None),
                       walk_frames(name, len(contacts)),
                       halves(len(contacts), standing(first), standing(second)))


def walk_frames(name: str, frames: int) -> NDArray[np.bool_]:
    """The frames of transition ``name`` ("walk2trot", ...) that play as the walk: the synthesis
    counts a transition as the hub it leaves over its first half, the one it reaches over its
    second (``plan_kernels``' ``first_half``)."""
    source, target = name.split("2")
    first = np.arange(frames) < frames // 2
    return np.asarray((first & (source == "walk")) | (~first & (target == "walk")))


def standing(clip: Motion) -> Floats:
    """(4,) the height each foot stands at in ``clip``: the median of its planted frames' (a foot
    never planted: its lowest)."""
    heights = clip.foot_positions()[..., UP_AXIS].astype(np.float64)
    return np.array([np.median(heights[clip.contacts[:, k], k]) if clip.contacts[:, k].any()
                     else heights[:, k].min() for k in range(heights.shape[1])])


def halves(frames: int, first: Floats, second: Floats) -> Floats:
    """``(frames, 4)``: ``first`` over a transition's first half, ``second`` over the rest -- the
    hubs the synthesis counts it as (:func:`walk_frames`)."""
    return np.where((np.arange(frames) < frames // 2)[:, None], first[None], second[None])


def hold_plants(motion: Motion, walk: NDArray[np.bool_] | None = None,
                stand: Floats | None = None) -> Motion:
    """Every plant held at its average place, swings eased between (as in the speed map), by IK.
    ``walk``: frames played as the walk, which keep two feet down as the walk's speed map does
    (a lifting foot held where it stood until another lands). ``stand (F, 4)``: the height each
    foot's plant stands at on each frame (:func:`halves` of the gaits' :func:`standing`), else its
    average's. A mocap paw's end site stands higher in one take than in another (the real dog's
    forepaws 16 mm in its walk, 30 mm in its trot, 22 mm in walk2trot): held at its own take's
    height, a transition's paw stood 1-1.5 cm under the paw of the gait it plays as, and
    that gait's last 2-3 cm of every landing and first of every lift-off swept along in the
    1 cm band of the strict plants (issue 27)."""
    feet = motion.foot_positions()
    if walk is not None:
        held = C.hold_down(motion.contacts, LEAST_DOWN["walk"], cyclic=False, where=walk)
        feet = held_feet(feet, motion.contacts, held)
        motion = motion.with_contacts(held)
    root = np.asarray(motion.root_pos, np.float64)
    targets = foot_targets(feet, root, root[None], motion.contacts, cyclic=False, stand=stand)[0]
    rigs = ik.limb_rigs(motion.skeleton)
    limit = reach_limit(motion, rigs)

    def place(pose: NDArray[np.floating]) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
        # As in the speed maps, the root sinks where a plant would lock a leg straight (a straight
        # leg has no bend side; the synthesis's foot lock would then pick one frame by frame).
        sunk = sink_for_reach(motion, root, pose, targets, rigs, ease=REACH_EASE_FRAMES,
                              most=MAX_SINK * motion.skeleton.leg_length())
        # Deeper than that, the foot falls short of its plant (slides a little) instead.
        return sunk, ik.within_reach(motion.skeleton, sunk, pose, targets, limit, rigs)

    axes = ik.hinge_axes_over_time(motion.skeleton, motion.rotations, rigs)
    rotations, _, sunk = solve_eased(motion.skeleton, motion.rotations, place, rigs,
                                     float(feet[..., UP_AXIS].min()), axes, cyclic=False,
                                     contacts=motion.contacts)
    return Motion(motion.skeleton, sunk.astype(np.float32), rotations, motion.fps, motion.contacts,
                  motion.name, motion.gait)
