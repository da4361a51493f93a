"""A mocap take's clip made fit for a library (:mod:`synth_core.build.manifest`): a stride made to
loop where it nearly does, every clip put on one ground, a standing clip held from a gait's frame."""

from __future__ import annotations

import numpy as np

from synth_core import UP_AXIS
from synth_core.motion import contacts as C
from synth_core.motion import quat
from synth_core.motion.clip import Motion

LOOP_CLOSE_MAX_DEG = 30.0  # a leg joint turning more than this over the seam: not a repeating stride
# (the real dog's clean strides: 5-28 deg; a braking gallop's last stride: 78)


def loop_error(cycle: Motion, following: Motion) -> tuple[str, float]:
    """The leg joint whose rotation differs most (deg) between a cycle's first frame and the
    frame ``following`` it, and that angle."""
    legs = sorted({j for foot in cycle.skeleton.feet for j in foot.chain[:-1]})
    delta = quat.mul(cycle.rotations[0, legs], quat.inv(following.rotations[0, legs]))
    turn = np.degrees(2 * np.arccos(np.clip(np.abs(delta[:, 3]), 0.0, 1.0)))
    k = int(np.argmax(turn))
    return cycle.skeleton.names[legs[k]], float(turn[k])


def close_loop(cycle: Motion, following: Motion) -> Motion:
    """A mocap stride made to loop: the pose of the frame ``following`` it in the take (the next
    stride's first) is brought onto its own first pose, the difference spread evenly over it.

    A stride cut from a take never quite closes (the real dog's: 0.6-0.9 cm per joint on
    average, the swinging paw several cm), and a speed map plays it as a loop: the paw then
    jumped at every stride's seam -- 5-8 cm in one frame where the take itself moves 2-4 cm.
    """
    F, J = cycle.n_frames, cycle.skeleton.n_joints
    share = np.arange(F, dtype=np.float64) / F
    delta = quat.mul(cycle.rotations[0], quat.inv(following.rotations[0]))
    fix = quat.slerp(quat.identity((F, J), np.float64), np.broadcast_to(delta, (F, J, 4)), share[:, None])
    root = cycle.root_pos.astype(np.float64)
    root[:, UP_AXIS] += share * float(cycle.root_pos[0, UP_AXIS] - following.root_pos[0, UP_AXIS])
    return Motion(cycle.skeleton, root.astype(np.float32), quat.mul(fix, cycle.rotations).astype(np.float32),
                  cycle.fps, cycle.contacts, cycle.name, cycle.gait)


def on_the_ground(clip: Motion) -> Motion:
    """The clip raised or lowered so its planted feet stand at height 0 (:func:`C.plant_level`).

    Each take's floor and paw markers sit a little differently (the real dog's planted paws at
    -0.8 to +2.7 cm); a library puts every clip on one ground, so one clip's paws would float
    (2 cm while the dog stands) where another's sink into the floor.
    """
    level = C.plant_level(clip.contacts, clip.foot_positions()[..., UP_AXIS])
    if level is None:
        return clip
    root = clip.root_pos.copy()
    root[:, UP_AXIS] -= level
    return Motion(clip.skeleton, root, clip.rotations, clip.fps, clip.contacts, clip.name, clip.gait)


def still_clip(like: Motion, seconds: float = 2.0) -> Motion:
    """Standing still: the cycle's frame with the most feet down (ties: the lowest feet), held."""
    feet_y = like.foot_positions()[..., UP_AXIS]
    score = like.contacts.sum(axis=1) - feet_y.sum(axis=1)
    f = int(np.argmax(score))
    n = int(round(seconds * like.fps))
    root = np.repeat(like.root_pos[f:f + 1], n, axis=0)
    return Motion(like.skeleton, root, np.repeat(like.rotations[f:f + 1], n, axis=0), like.fps,
                  np.ones((n, 4), bool), "idle", "static")


def stand_as(clip: Motion, idle: Motion, at_start: bool) -> Motion:
    """A start (``at_start``) or a stop whose standing frames stand as the idle does: raised or
    lowered there by the difference of their feet's heights, easing back to the clip's own level
    (:func:`on_the_ground`, set by its walking plants) over its first step out of (or last into)
    the stance.

    Each clip is put on the ground by its own plants: a start's are mostly walking ones, where the
    real dog's paw end sites stand about 1 cm lower than standing, so its standing frames (the same
    frames of the same take as the idle's last ones) stood 0.8-0.9 cm above the idle's and every
    real-dog character started floating that high (issue 27: floating <= 1 cm)."""
    contacts = clip.contacts if at_start else clip.contacts[::-1]
    moving = np.flatnonzero(~contacts.all(axis=1))
    if len(moving) == 0:
        return clip
    still = int(moving[0])  # frames standing at the static end
    if still == 0:
        return clip
    lifted = int(np.flatnonzero(~contacts[still])[0])  # the first foot to step
    down = np.flatnonzero(contacts[still:, lifted])
    step = int(down[0]) if len(down) else len(contacts) - still  # its swing, frames
    heights = clip.foot_positions()[:, :, UP_AXIS]
    heights = heights if at_start else heights[::-1]
    offset = float(np.median(np.median(idle.foot_positions()[:, :, UP_AXIS], axis=0) - heights[:still]))
    u = np.clip((np.arange(len(contacts)) - still + 1) / max(step + 1, 1), 0.0, 1.0)
    weight = 1.0 - u * u * (3 - 2 * u)
    root = clip.root_pos.astype(np.float64)
    root[:, UP_AXIS] += offset * (weight if at_start else weight[::-1])
    return Motion(clip.skeleton, root.astype(np.float32), clip.rotations, clip.fps, clip.contacts,
                  clip.name, clip.gait)
