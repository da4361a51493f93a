"""A generated leg's joint angles over a clip (:mod:`synth_core.builtin.generator`, step 5): the
sagittal solve of :mod:`synth_core.builtin.limbs` driven by the foot's path, with the carpus and
hock flexing in swing, the fetlock sinking under load, the hoof breaking over its toe late in the
stance, the girdle and the distal joint's reach corrections eased in time, mid-swing smoothed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from synth_core.builtin.foot_paths import FULL_FLEX_SWING_S, FootPlan
from synth_core.builtin.limbs import MIN_DISTAL_FLEX, LegSolution, Limb, angle_of, solve_leg
from synth_core.builtin.tracks import FPS, Floats, smoothstep
from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton

BREAKOVER_SHARE = 0.2  # of the stance: the hoof or paw rolls over its toe only in this last part
BROKEN_AT_LIFT = 0.4  # of the breakover angle reached at lift-off; the rest early in the swing
_X = np.array([1.0, 0.0, 0.0])


def rot_x(angle: Floats) -> NDArray[np.floating]:
    """Rotations about +X (the sagittal plane's normal) by ``angle`` (rad)."""
    return quat.from_axis_angle(_X, angle)


def rest_protraction(limb: Limb, rest_pos: NDArray[np.floating]) -> float:
    """Standing angle (from straight down) of the line from the limb root to the toe."""
    return float(angle_of(rest_pos[limb.chain[-1], [2, 1]] - rest_pos[limb.chain[0], [2, 1]]))


def leg_rotations(skeleton: Skeleton, limb: Limb, bone_angles: Floats,
                   global_pitch: Floats) -> NDArray[np.floating]:
    """Local rotations (F, B, 4) of a leg's chain joints from its bones' world sagittal angles."""
    parent_pitch = global_pitch[:, skeleton.parents[limb.chain[0]]]
    bone_global = limb.rest_angles[None] - bone_angles  # X-rotation of each chain joint in the world
    return rot_x(np.diff(np.concatenate([parent_pitch[:, None], bone_global], axis=1), axis=1))


def solve_limb(skeleton: Skeleton, limb: Limb, plan: FootPlan, trunk_pos: Floats,
                global_pitch: Floats, v: dict[str, Floats], rest_protraction: float) -> LegSolution:
    in_stance = plan.planted
    w = np.nan_to_num(plan.stance_w)
    s = np.nan_to_num(plan.swing_s)
    # Flexion rises from zero slope at lift-off (no pop) and peaks early in swing; a short swing
    # (the first steps of a start) flexes less, as a joint can only fold so fast.
    short = np.clip(np.nan_to_num(plan.swing_frames) / (FULL_FLEX_SWING_S * FPS), 0.0, 1.0)
    swing_bump = np.where(in_stance, 0.0, short * np.sin(np.pi * s**0.75) ** 2)
    load = np.where(in_stance, np.sin(np.pi * w), 0.0)
    fore = limb.girdle is not None
    distal = np.radians(np.where(fore, v["carpus_flex"], v["hock_flex"])) * swing_bump
    if not fore:
        distal = distal + np.radians(v["hock_load"]) * load
    # Digits: the fetlock sinks under load; the hoof breaks over the toe; the digits fold in swing.
    # The hoof (paw) stands flat through the stance and breaks over its toe in the last
    # BREAKOVER_SHARE of it (issue 28: a hoof rolling on its toe all stance long reads wrong).
    # Part of it by lift-off (easing in), the rest early in the swing as the heel rises further,
    # then it unwinds: a quick stance (a gallop's 8 frames) breaks over without a snap. The bones
    # above the hoof (the pastern) turn from mid-stance on, as the fetlock rises off its sink:
    # that moves the fetlock, not the hoof, and leaves the leg the reach it has at lift-off.
    over = np.clip((w - 1.0 + BREAKOVER_SHARE) / BREAKOVER_SHARE, 0.0, 1.0)
    after = np.where(s < 0.25, BROKEN_AT_LIFT + (1 - BROKEN_AT_LIFT) * np.sin(0.5 * np.pi * s / 0.25),
                     1.0 - smoothstep((s - 0.25) / 0.4))
    hoof = np.where(in_stance, BROKEN_AT_LIFT * over**2, after)
    pastern = np.where(in_stance, smoothstep((w - 0.5) / 0.5), 1.0 - smoothstep(s / 0.5))
    digits = list(limb.digits)
    breakover = np.radians(v["breakover"])[:, None] * np.concatenate(
        [np.repeat(pastern[:, None], len(digits) - 1, axis=1), hoof[:, None]], axis=1)
    digit_angles = limb.rest_angles[digits][None] - breakover \
        - np.radians(v["digit_flex"])[:, None] * swing_bump[:, None]
    if len(digits) > 1:  # the pastern sinks; a lone digit bone is the paw itself, kept flat
        digit_angles[:, 0] += np.radians(v["fetlock_sink"]) * load
    root = trunk_pos[:, limb.chain[0]][:, [2, 1]]
    foot = np.stack([plan.z, plan.y], axis=1)
    girdle = None
    if fore:
        # The scapula rides with the trunk's pitch and swings with the leg: about a third of the
        # leg's protraction from standing (the shoulder blade's share of forelimb swing).
        trunk = global_pitch[:, skeleton.parents[limb.chain[0]]]
        girdle = limb.rest_angles[limb.girdle] - trunk + 0.35 * (angle_of(foot - root) - rest_protraction)
    # Reach adaptation: full in stance, fading out over the first and in over the last 30% of swing.
    adapt = np.where(in_stance, 1.0, np.maximum(1.0 - smoothstep(s / 0.3), smoothstep((s - 0.7) / 0.3)))
    first = solve_leg(limb, root, foot, girdle, distal, digit_angles, adapt=adapt)
    if girdle is not None:
        girdle = girdle + _ease(first.angles[:, limb.girdle] - girdle)
    # (Eased, the opening may reach frames whose own flexion is smaller: keep the joint's limit.)
    distal = np.maximum(distal + _ease(first.distal_flex - distal),
                        np.minimum(MIN_DISTAL_FLEX[limb.flex_sign], distal))
    solution = solve_leg(limb, root, foot, girdle, distal, digit_angles, adapt=adapt)
    return replace(solution, angles=_smooth_swing(solution.angles, in_stance, s))


SWING_SMOOTHING = 1.5  # frames (Gaussian sigma) over the middle of a swing


def _smooth_swing(angles: Floats, in_stance: NDArray[np.bool_], s: Floats) -> Floats:
    """Bone angles (F, B) smoothed in time in mid-swing, untouched near and in stance.

    Mid-swing the leg is folded high, where the two-link solution turns fastest as the fetlock
    nears the shoulder or hip (a one-frame kink of the elbow or stifle); there the toe path is
    only a guide, so its curve may give a little. Near lift-off and touchdown nothing changes.
    """
    smoothed = gaussian_filter1d(angles, SWING_SMOOTHING, axis=0, mode="nearest")
    weight = np.where(in_stance, 0.0, smoothstep((np.minimum(s, 1.0 - s) - 0.15) / 0.2))
    return np.asarray(angles + weight[:, None] * (smoothed - angles))


def _ease(correction: Floats, frames: int = 9) -> Floats:
    """A reach correction spread out in time: at least as large where it was needed, no step.

    Corrections found frame by frame switch on where the foot first runs out of reach, so the
    girdle or hock would jump. A running maximum of each sign's magnitude, then a Gaussian, starts
    them earlier and eases them in and out.
    """
    up = gaussian_filter1d(maximum_filter1d(np.maximum(correction, 0.0), frames, mode="nearest"),
                           frames / 4, mode="nearest")
    down = gaussian_filter1d(maximum_filter1d(np.maximum(-correction, 0.0), frames, mode="nearest"),
                             frames / 4, mode="nearest")
    return np.asarray(up - down)
