"""Limb IK for speed maps (Sung 2011, section 3, Fig. 5), vectorized over any leading axes.

Each leg is solved as a two-link chain, the paper's four steps in order:

1. **Hinge angle, analytically.** The hinge (elbow, stifle) turns the shin about the hinge axis
   until the limb root reaches the ankle target at the right distance. The axis is thigh x shin,
   ``(P_h - P_r) x (P_a - P_h)``; where that is shorter than a threshold (a nearly straight leg,
   whose thigh x shin flips sign from frame to frame: "hinge popping") it falls back to
   ``(P_h - P_r) x (P_t - P_h)`` with the toe P_t, as in the paper, signed to agree with the
   limb's dominant bend over the whole clip; if that too is degenerate, the dominant bend axis
   itself. The turn about the axis is solved exactly on the circle the ankle sweeps, so any axis
   (not only one perpendicular to the shin) reaches the target.
2. **Swing.** The smallest rotation of the limb root taking root->ankle onto root->target.
3. **End effector orientation.** The last bone (ankle -> toe) keeps its world orientation from
   the source frame, so a hoof or paw stays as flat as it was; where that would put the ankle
   under the ground, it is tipped (about the toe) just enough to bring the ankle to ground level.
4. **Stretch.** Only when the target is beyond the straightened limb: thigh and shin bones are
   lengthened by the missing factor, which is reported (``IKResult.stretch``); apply it with
   :func:`stretched_offsets`.

**Legs of more than two segments.** Quadruped legs have 3-5 segments below the girdle. We keep
the distal segments' relative angles: the joints between the hinge and the ankle (the carpus and
fetlock in front, the hock and fetlock behind) keep their source rotations, so the hinge-to-ankle
sub-chain moves as one rigid "shin". The girdle (scapula) keeps its source rotation too; the
upper joint (shoulder, hip) and the hinge are solved. This keeps each gait's characteristic
distal flexion (the folded carpus in swing, the sinking fetlock in stance) intact at every speed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core import UP_AXIS
from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton, forward_kinematics

Floats = NDArray[np.floating]

HINGE_AXIS_MIN_SIN = np.sin(np.radians(5.0))  # thigh x shin shorter than this (unit vectors): fall back
REACH_TOLERANCE = 1e-6  # m: closer than this counts as reached (no stretch for rounding)
_EPS = 1e-9


@dataclass(frozen=True)
class LimbRig:
    """The joints IK works with on one leg (indices into the skeleton)."""

    foot: str
    upper: int  # limb root P_r: shoulder / hip; its rotation swings the limb
    hinge: int  # P_h: elbow / stifle; the only joint that bends
    ankle: int  # P_a: parent of the end effector; its world rotation is kept (step 3)
    effector: int  # P_t: the toe, touching the ground
    shin: tuple[int, ...]  # joints after the hinge down to the ankle (their bones form the shin)


def limb_rigs(skeleton: Skeleton, uppers: Mapping[str, str] | None = None) -> tuple[LimbRig, ...]:
    """The four legs' IK joints. ``uppers`` names a foot's upper joint where the default is wrong.

    Default upper joint: for a fore limb whose chain has a girdle (5 or more joints from the limb
    root to the toe, e.g. shoulder blade, arm, forearm, hand, toe), the chain's second joint;
    otherwise the first (the hip). The hinge is the upper joint's child in the chain.
    """
    rigs = []
    for foot in skeleton.feet:
        chain = foot.chain
        if uppers and foot.name in uppers:
            upper = skeleton.index(uppers[foot.name])
            if upper not in chain:
                raise ValueError(f"ik.{foot.name}: {uppers[foot.name]!r} is not on the leg "
                                 f"{[skeleton.names[j] for j in chain]}")
        else:
            upper = chain[1] if foot.name[1] == "F" and len(chain) >= 5 else chain[0]
        i = chain.index(upper)
        if i + 2 > len(chain) - 2:
            raise ValueError(f"ik.{foot.name}: the leg below {skeleton.names[upper]!r} needs an upper "
                             "bone, a hinge, an ankle and a toe")
        rigs.append(LimbRig(foot.name, upper, chain[i + 1], chain[-2], chain[-1],
                            tuple(chain[i + 2:-1])))
    return tuple(rigs)


@dataclass(frozen=True)
class IKResult:
    rotations: NDArray[np.float32]  # (..., J, 4) local
    stretch: Floats  # (..., 4) limb length factor per foot, 1 where the target was reachable
    miss: Floats  # (..., 4) metres the foot misses its target by without the stretch
    wrong_side: NDArray[np.bool_]  # (..., 4) hinge bent against its axis (a flip; see mend_flips)


def _unit(v: Floats) -> Floats:
    return np.asarray(v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS))


def _dot(a: Floats, b: Floats) -> Floats:
    return np.asarray(np.sum(a * b, axis=-1))


def bend_axis(thigh: Floats, shin: Floats, root_rot: Floats) -> Floats:
    """A limb's dominant bend axis (3,), unit, in the root's frame: thigh x shin summed over
    every pose given (``(..., 3)`` world vectors, ``root_rot (..., 4)``)."""
    local = quat.rotate(quat.inv(root_rot), np.cross(_unit(thigh), _unit(shin)))
    return _unit(local.reshape(-1, 3).sum(axis=0))


def bend_axes(skeleton: Skeleton, rotations: NDArray[np.floating],
              rigs: tuple[LimbRig, ...] | None = None) -> Floats:
    """Each leg's dominant bend axis (4, 3) in the root's frame over poses ``(..., J, 4)``."""
    rigs = limb_rigs(skeleton) if rigs is None else rigs
    rotations = np.asarray(rotations, np.float64)
    pos, rot = forward_kinematics(skeleton, np.zeros((*rotations.shape[:-2], 3)), rotations)
    pos, root_rot = np.asarray(pos, np.float64), np.asarray(rot, np.float64)[..., 0, :]
    return np.stack([bend_axis(pos[..., r.hinge, :] - pos[..., r.upper, :],
                               pos[..., r.ankle, :] - pos[..., r.hinge, :], root_rot) for r in rigs])


def leg_ranges(positions: NDArray[np.floating], rigs: tuple[LimbRig, ...]) -> Floats:
    """Each leg's range, ``(4, 2)``, over poses (their joints' positions ``(..., J, 3)``): its
    furthest fold, the least cosine of the angle between thigh and shin (1: straight, -1: the
    shin folded back onto the thigh), and its longest reach, upper joint to ankle (the poses'
    unit). The render's sink lowers the body no further than lets every leg reach its target
    folded no more than this, nor raises it for that further than every leg reaches its own
    within the longest (foot_kernels.fold_room);
    it sinks it where a leg would reach past the longest and footlock.LONGEST_OVER, and the IK
    reaches no further (foot_kernels.reach_sink, limb_kernels.solve_legs)."""
    pos = np.asarray(positions, np.float64)
    out = np.empty((len(rigs), 2))
    for k, r in enumerate(rigs):
        thigh, shin = pos[..., r.hinge, :] - pos[..., r.upper, :], pos[..., r.ankle, :] - pos[..., r.hinge, :]
        out[k] = _dot(_unit(thigh), _unit(shin)).min(), np.linalg.norm(thigh + shin, axis=-1).max()
    return out


def _hinge_axes(thigh: Floats, shin: Floats, toe: Floats, root_rot: Floats,
                bend: Floats | None = None) -> Floats:
    """Step 1's axis, (..., 3) world, unit (see the module docstring). ``bend (3,)``: the limb's
    dominant bend in the root's frame (default: over the poses given)."""
    primary = np.cross(_unit(thigh), _unit(shin))
    by_toe = np.cross(_unit(thigh), _unit(toe))
    # The limb's dominant bend over the clip, in the body's frame, so a turning clip agrees too.
    bend = bend_axis(thigh, shin, root_rot) if bend is None else np.asarray(bend, np.float64)
    dominant = quat.rotate(root_rot, bend)
    # Both axes point the dominant way: the hinge then only ever flexes. Thigh x shin on its
    # own flips where the source's shin sub-chain (with a flexed carpus or hock) swings past the
    # thigh line; a target needing more bend there would be reached by hyperextending the hinge
    # on one frame and flexing it on the next (a horse's slow gallop popped 80 deg in a frame).
    primary = primary * np.where(_dot(primary, dominant) < 0, -1.0, 1.0)[..., None]
    by_toe = by_toe * np.where(_dot(by_toe, dominant) < 0, -1.0, 1.0)[..., None]
    ok = np.linalg.norm(primary, axis=-1) >= HINGE_AXIS_MIN_SIN
    toe_ok = np.linalg.norm(by_toe, axis=-1) >= HINGE_AXIS_MIN_SIN
    axis = np.where(ok[..., None], primary, np.where(toe_ok[..., None], by_toe, dominant))
    return _unit(axis)


LINK_MIN_COS = 0.5  # consecutive frames' hinge axes closer than this (60 deg) to perpendicular:
# no telling whether the bend kept its side or reversed, so the sequence is cut there


def _segment_ids(link: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Per frame, the index of the run it is in; a new run starts at every True of ``link``."""
    return np.asarray(np.cumsum(link), np.int64)


def hinge_axes_over_time(skeleton: Skeleton, rotations: NDArray[np.floating],
                         rigs: tuple[LimbRig, ...] | None = None, cyclic: bool = False) -> Floats:
    """Each leg's hinge axis ``(F, 4, 3)`` in the root's frame for a pose sequence ``(F, J, 4)``,
    on the side the source bends that frame and kept continuous from frame to frame.

    Step 1's axis of each frame (thigh x shin; the paper's toe fallback where the leg is nearly
    straight; the dominant bend where that fails too) is taken with the source's own sign, then
    re-signed along time: where two consecutive frames' axes point opposite ways (the source's
    bend reversing in one frame -- a mocap glitch, or a leg lifted with its bend plane turned
    past the body's side), the later one is turned back, so the hinge keeps its side. Where two
    consecutive axes are nearly perpendicular, no side can be read from the pair: the sequence is
    cut there, and each run between cuts takes the side of the limb's dominant bend (weighted by
    how bent its frames are) -- today's per-frame rule, for the run as a whole. Signing every
    frame by the dominant bend alone flips a hinge wherever its plane turns more than 90 deg from
    the dominant (the real dog's fore leg raised to the side while turning): the IK then bends
    the elbow the other way for those frames, a paw jump in and out of them.

    ``cyclic``: the sequence loops (a gait cycle): the last frame links to the first.
    """
    rigs = limb_rigs(skeleton) if rigs is None else rigs
    rotations = np.asarray(rotations, np.float64)
    F = rotations.shape[0]
    pos, rot = forward_kinematics(skeleton, np.zeros((F, 3)), rotations)
    pos, root_rot = np.asarray(pos, np.float64), np.asarray(rot, np.float64)[:, 0]
    axes = np.empty((F, len(rigs), 3))
    for k, rig in enumerate(rigs):  # legs: four
        thigh, shin = pos[:, rig.hinge] - pos[:, rig.upper], pos[:, rig.ankle] - pos[:, rig.hinge]
        toe = pos[:, rig.effector] - pos[:, rig.hinge]
        bend = bend_axis(thigh, shin, root_rot)
        primary = np.cross(_unit(thigh), _unit(shin))
        by_toe = np.cross(_unit(thigh), _unit(toe))
        weight = np.linalg.norm(primary, axis=-1)
        ok = weight >= HINGE_AXIS_MIN_SIN
        toe_ok = np.linalg.norm(by_toe, axis=-1) >= HINGE_AXIS_MIN_SIN
        world = np.where(ok[:, None], primary, np.where(toe_ok[:, None], by_toe, quat.rotate(root_rot, bend)))
        local = _unit(quat.rotate(quat.inv(root_rot), world))
        axes[:, k] = _continuous(local, weight, bend, cyclic)
    return axes


def _continuous(axis: Floats, weight: Floats, bend: Floats, cyclic: bool) -> Floats:
    """Axes ``(F, 3)`` re-signed along time (see :func:`hinge_axes_over_time`)."""
    F = len(axis)
    link = _dot(axis[1:], axis[:-1])  # frame f's axis against frame f - 1's
    cut = np.abs(link) < LINK_MIN_COS
    start = 0
    if cyclic and F > 1:
        seam = float(_dot(axis[0], axis[-1]))
        cuts = np.flatnonzero(np.append(cut, abs(seam) < LINK_MIN_COS))
        # Start the chain just after a cut (the seam's if that is one) so no run crosses one.
        start = (int(cuts[-1]) + 1) % F if len(cuts) else 0
        order = np.roll(np.arange(F), -start)
        axis, weight = axis[order], weight[order]
        link = _dot(axis[1:], axis[:-1])
        cut = np.abs(link) < LINK_MIN_COS
    flips = np.concatenate([[1.0], np.where(cut | (link >= 0), 1.0, -1.0)])
    chained = axis * np.cumprod(flips)[:, None]
    run = _segment_ids(np.concatenate([[False], cut]))
    side = np.bincount(run, weights=weight * _dot(chained, bend[None]))
    signed = chained * np.where(side < 0, -1.0, 1.0)[run][:, None]
    return np.roll(signed, start, axis=0) if start else signed


def _turn_to_distance(thigh: Floats, shin: Floats, axis: Floats, distance: Floats) -> Floats:
    """Angle (...,) to turn ``shin`` about ``axis`` so that |thigh + shin'| = distance (or nearest).

    |thigh + R shin|^2 = |thigh|^2 + |shin|^2 + 2 thigh . R shin, and by Rodrigues
    thigh . R shin = c + a cos(phi) + b sin(phi): solve a cos + b sin = want.
    """
    along = _dot(axis, shin)
    c = _dot(thigh, axis) * along
    a = _dot(thigh, shin) - c
    b = _dot(thigh, np.cross(axis, shin))
    want = 0.5 * (distance**2 - _dot(thigh, thigh) - _dot(shin, shin)) - c
    amp = np.hypot(a, b)
    base = np.arctan2(b, a)
    spread = np.arccos(np.clip(want / np.maximum(amp, _EPS), -1.0, 1.0))
    candidates = np.stack([base - spread, base + spread], axis=-1)
    candidates = (candidates + np.pi) % (2 * np.pi) - np.pi
    # The two solutions bend the leg to either side; keep the side the axis says (positive bend
    # about it: for thigh x shin, the source's own side), then the smaller turn.
    turned = quat.rotate(quat.from_axis_angle(axis[..., None, :], candidates), shin[..., None, :])
    side = _dot(axis[..., None, :], np.cross(thigh[..., None, :], turned)) > 0
    cost = np.abs(candidates) + np.where(side, 0.0, 10.0)
    pick = cost.argmin(axis=-1)[..., None]
    return np.asarray(np.take_along_axis(candidates, pick, axis=-1)[..., 0])


def _keep_above_ground(toe_target: Floats, ankle_to_toe: Floats, ground: float) -> Floats:
    """Tip the ankle->toe vector (about the toe) so the ankle is not below the ground."""
    up = UP_AXIS
    limit = toe_target[..., up] - ground  # ankle height = toe - vector's rise; must be >= ground
    rise = ankle_to_toe[..., up]
    length = np.linalg.norm(ankle_to_toe, axis=-1)
    new_rise = np.minimum(rise, np.minimum(limit, length))
    flat = ankle_to_toe.copy()
    flat[..., up] = 0.0
    flat_len = np.linalg.norm(flat, axis=-1)
    scale = np.sqrt(np.maximum(length**2 - new_rise**2, 0.0)) / np.maximum(flat_len, _EPS)
    tipped = flat * scale[..., None]
    tipped[..., up] = new_rise
    return np.where((rise > limit)[..., None], tipped, ankle_to_toe)


def _checked_targets(targets: NDArray[np.floating], n_legs: int, ground: float | None) -> Floats:
    """``targets (..., n_legs, 3)`` as a float64 copy, raised onto ``ground`` (None: left)."""
    targets = np.array(targets, dtype=np.float64)
    if targets.shape[-2:] != (n_legs, 3):
        raise ValueError(f"Expected `targets` to have shape (..., {n_legs}, 3), got {targets.shape}")
    if ground is not None:
        targets[..., UP_AXIS] = np.maximum(targets[..., UP_AXIS], ground)
    return targets


def _ankle_goal(ankle_rot: Floats, toe_offset: Floats, p_toe: Floats, target: Floats,
                ground: float | None) -> tuple[Floats, Floats]:
    """Step 3 (first, as it fixes where the ankle must go): the ankle's world rotation and the
    ankle's target. The last bone keeps its world orientation, tipped where the ankle would be
    under the ground."""
    ankle_to_toe = quat.rotate(ankle_rot, np.broadcast_to(toe_offset, p_toe.shape))
    if ground is not None:
        tipped = _keep_above_ground(target, ankle_to_toe, ground)
        ankle_rot = quat.mul(quat.between(ankle_to_toe, tipped), ankle_rot)
        ankle_to_toe = tipped
    return ankle_rot, target - ankle_to_toe


def solve(skeleton: Skeleton, root_pos: NDArray[np.floating], rotations: NDArray[np.floating],
          targets: NDArray[np.floating], rigs: tuple[LimbRig, ...] | None = None,
          ground: float | None = 0.0, bends: NDArray[np.floating] | None = None,
          axes: NDArray[np.floating] | None = None) -> IKResult:
    """Put each foot's toe on its target: ``targets (..., 4, 3)`` world, FOOT_NAMES order.

    ``root_pos (..., 3)`` and local ``rotations (..., J, 4)`` are the pose to adjust (leading
    axes: frames, clips, ...). ``ground``: height no toe or ankle goes below (None: no ground).
    Rotations of the upper joint, the hinge and the ankle change; nothing else does.
    ``bends (4, 3)``: each leg's dominant bend axis in the root's frame (:func:`bend_axes`;
    default: over the poses given). ``axes (..., 4, 3)``: each leg's hinge axis per pose in the
    root's frame, broadcast against the leading axes (:func:`hinge_axes_over_time`: a sequence's
    hinge side kept continuous); given, it replaces step 1's per-pose choice.
    """
    rigs = limb_rigs(skeleton) if rigs is None else rigs
    local = np.array(rotations, dtype=np.float64)
    targets = _checked_targets(targets, len(rigs), ground)
    pos, rot = forward_kinematics(skeleton, np.asarray(root_pos, dtype=np.float64), local)
    pos, rot = np.asarray(pos, np.float64), np.asarray(rot, np.float64)
    offs = np.asarray(skeleton.offsets, dtype=np.float64)
    lead = local.shape[:-2]
    stretch = np.ones((*lead, len(rigs)))
    miss = np.zeros((*lead, len(rigs)))
    wrong = np.zeros((*lead, len(rigs)), bool)
    for k, rig in enumerate(rigs):
        target = targets[..., k, :]
        p_root, p_hinge, p_ankle, p_toe = (pos[..., j, :] for j in (rig.upper, rig.hinge, rig.ankle,
                                                                    rig.effector))
        ankle_rot, ankle_target = _ankle_goal(rot[..., rig.ankle, :], offs[..., rig.effector, :], p_toe,
                                              target, ground)
        # Step 1: the hinge.
        thigh, shin = p_hinge - p_root, p_ankle - p_hinge
        if axes is None:
            axis = _hinge_axes(thigh, shin, p_toe - p_hinge, rot[..., 0, :],
                               None if bends is None else bends[k])
        else:
            axis = _unit(quat.rotate(rot[..., 0, :], np.asarray(axes, np.float64)[..., k, :]))
        distance = np.linalg.norm(ankle_target - p_root, axis=-1)
        bend = quat.from_axis_angle(axis, _turn_to_distance(thigh, shin, axis, distance))
        shin = quat.rotate(bend, shin)
        # No turn about the axis bends the leg its way (both solutions lie on the other side):
        # the pose found is the hinge's mirror image, a flip (:func:`mend_flips` blends it out).
        wrong[..., k] = _dot(np.cross(_unit(thigh), _unit(shin)), axis) < -HINGE_AXIS_MIN_SIN
        reach = np.linalg.norm(thigh + shin, axis=-1)
        # Step 2: swing the limb onto the target.
        swing = quat.between(thigh + shin, ankle_target - p_root)
        # Step 4: stretch what is still missing.
        short = distance - reach > REACH_TOLERANCE
        miss[..., k] = np.where(short, distance - reach, 0.0)
        stretch[..., k] = np.where(short, distance / np.maximum(reach, _EPS), 1.0)
        # Back to local rotations: upper, hinge (its parent is the upper), and the ankle, whose
        # parent turned with everything between the hinge and it.
        upper_world = quat.mul(swing, rot[..., rig.upper, :])
        hinge_world = quat.mul(swing, quat.mul(bend, rot[..., rig.hinge, :]))
        parent_upper = rot[..., skeleton.parents[rig.upper], :]
        local[..., rig.upper, :] = quat.mul(quat.inv(parent_upper), upper_world)
        local[..., rig.hinge, :] = quat.mul(quat.inv(upper_world), hinge_world)
        ankle_parent = quat.mul(swing, quat.mul(bend, rot[..., skeleton.parents[rig.ankle], :]))
        local[..., rig.ankle, :] = quat.mul(quat.inv(ankle_parent), ankle_rot)
    return IKResult(quat.normalize(local).astype(np.float32), stretch, miss, wrong)


def mend_flips(rotations: NDArray[np.floating], wrong: NDArray[np.bool_],
               rigs: tuple[LimbRig, ...], cyclic: bool = False) -> NDArray[np.float32]:
    """Solved rotations ``(..., F, J, 4)`` with each leg's flipped frames (``wrong (..., F, 4)``,
    :attr:`IKResult.wrong_side`) replaced: the leg's solved joints blended (nlerp) between the
    nearest frames before and after that bend the right way. Frames are the last leading axis.
    A flipped frame misses its target a little; a flip would show as a paw jump in and out."""
    out = np.array(rotations, np.float32)
    F = out.shape[-3]
    t = np.arange(F)
    for k, rig in enumerate(rigs):  # legs: four
        bad = np.asarray(wrong[..., k], bool)
        if not bad.any():
            continue
        good = ~bad
        span = 3 * F if cyclic else F  # looped: the good frames of the loops either side count
        tiled = np.concatenate([good] * 3, axis=-1) if cyclic else good
        idx = np.arange(span) - (F if cyclic else 0)
        before = np.maximum.accumulate(np.where(tiled, idx, -10 * F), axis=-1)
        after = np.flip(np.minimum.accumulate(np.flip(np.where(tiled, idx, 10 * F), -1), axis=-1), -1)
        sl = slice(F, 2 * F) if cyclic else slice(0, F)
        before, after = before[..., sl], after[..., sl]
        before = np.where(before < -F, after, before)  # none before: hold the next good frame
        after = np.where(after > 2 * F, before, after)
        ok = (before >= -F) & (after <= 2 * F)
        w = np.where(after > before, (t - before) / np.maximum(after - before, 1), 0.0)
        joints = [rig.upper, rig.hinge, rig.ankle]
        for j in joints:
            q = out[..., j, :]
            a = np.take_along_axis(q, (before % F)[..., None], axis=-2)
            b = np.take_along_axis(q, (after % F)[..., None], axis=-2)
            blended = quat.nlerp(a, b, w)
            out[..., j, :] = np.where((bad & ok)[..., None], blended, q)
    return out


def _limb_geometry(skeleton: Skeleton, root_pos: NDArray[np.floating], rotations: NDArray[np.floating],
                   rigs: tuple[LimbRig, ...]) -> tuple[Floats, Floats, Floats, Floats]:
    """Per leg (..., 4, 3): limb root, ankle and toe positions; and (..., 4) the full reach."""
    pos, _ = forward_kinematics(skeleton, np.asarray(root_pos, np.float64),
                                np.asarray(rotations, np.float64))
    pos = np.asarray(pos, np.float64)
    upper, hinge, ankle, toe = (pos[..., [getattr(r, name) for r in rigs], :]
                                for name in ("upper", "hinge", "ankle", "effector"))
    reach = np.linalg.norm(hinge - upper, axis=-1) + np.linalg.norm(ankle - hinge, axis=-1)
    return upper, ankle, toe, reach


def extension(skeleton: Skeleton, root_pos: NDArray[np.floating], rotations: NDArray[np.floating],
              rigs: tuple[LimbRig, ...] | None = None) -> Floats:
    """How straight each leg is, (..., 4): limb root to ankle over the straightened limb's reach."""
    rigs = limb_rigs(skeleton) if rigs is None else rigs
    upper, ankle, _, reach = _limb_geometry(skeleton, root_pos, rotations, rigs)
    return np.asarray(np.linalg.norm(ankle - upper, axis=-1) / np.maximum(reach, _EPS))


def sink_to_reach(skeleton: Skeleton, root_pos: NDArray[np.floating], rotations: NDArray[np.floating],
                  targets: NDArray[np.floating], limit: NDArray[np.floating],
                  rigs: tuple[LimbRig, ...] | None = None) -> Floats:
    """How far (...,) the root must sink for every toe target to need at most ``limit (4,)`` of
    its leg's reach (see :func:`extension`), 0 where it already does.

    A target ahead of or behind the hip is reached by lowering the hip, as a running animal
    does at full stride; only a target further out horizontally than the reach stays short.
    """
    rigs = limb_rigs(skeleton) if rigs is None else rigs
    upper, ankle, toe, reach = _limb_geometry(skeleton, root_pos, rotations, rigs)
    to_ankle = np.asarray(targets, np.float64) - (toe - ankle) - upper
    allowed = np.asarray(limit, np.float64) * reach
    across = np.linalg.norm(np.delete(to_ankle, UP_AXIS, axis=-1), axis=-1)
    below = -to_ankle[..., UP_AXIS]
    sink = below - np.sqrt(np.maximum(allowed**2 - across**2, 0.0))
    return np.asarray(np.maximum(sink, 0.0).max(axis=-1))


def within_reach(skeleton: Skeleton, root_pos: NDArray[np.floating], rotations: NDArray[np.floating],
                 targets: NDArray[np.floating], limit: NDArray[np.floating],
                 rigs: tuple[LimbRig, ...] | None = None) -> Floats:
    """Toe targets ``(..., 4, 3)`` pulled towards their limb roots where reaching them would
    straighten a leg beyond ``limit (4,)`` of its reach (see :func:`extension`): the foot then
    falls short of its target rather than locking the leg straight (no bend side)."""
    rigs = limb_rigs(skeleton) if rigs is None else rigs
    upper, ankle, toe, reach = _limb_geometry(skeleton, root_pos, rotations, rigs)
    to_ankle = np.asarray(targets, np.float64) - (toe - ankle) - upper
    distance = np.linalg.norm(to_ankle, axis=-1)
    allowed = np.asarray(limit, np.float64) * reach
    scale = np.minimum(1.0, allowed / np.maximum(distance, _EPS))
    return np.asarray(upper + to_ankle * scale[..., None] + (toe - ankle))


def stretched_offsets(skeleton: Skeleton, rigs: tuple[LimbRig, ...],
                      stretch: NDArray[np.floating]) -> NDArray[np.float64]:
    """Rest offsets (..., J, 3) with each leg's thigh and shin bones scaled by ``stretch (..., 4)``."""
    stretch = np.asarray(stretch, dtype=np.float64)
    scale = np.ones((*stretch.shape[:-1], skeleton.n_joints))
    for k, rig in enumerate(rigs):
        scale[..., [rig.hinge, *rig.shin]] = stretch[..., k, None]
    return np.asarray(skeleton.offsets, dtype=np.float64) * scale[..., None]
