"""Joints that pass through straight slowly enough to be played at any stride rate (issue 28).

A dog's wrist (and a toe, a hock, a horse's fetlock) bends both ways: hyperextended under the
load of a stance, flexed in the swing. At lift-off and touchdown it passes through straight, in
the real dog's mocap at up to 60-70 deg in one frame (the gallop's wrist: 34 deg one way, 34 the
other). Played at the clip's rate, one frame is then bent one way and the next the other way; played faster
(a small character's Froude tempo, a character asked to go faster than the fastest clip: up to
``MAX_RATE`` 1.6, so a shown frame may skip one clip frame) or blended, two shown frames straddle
straight while both are clearly bent -- the joint reads as flipping its bend side in one frame
(``metrics.limb_flips``: turned by more than 90 deg while bent 15 deg or more in both).

So each crossing faster than :data:`CROSS_STEP_DEG` a frame is slowed down in time to that pace
at its centre (faster again a frame or two either side, where the joint is bent), the joint
following its own path (its local rotations resampled along the clip), spending longer near
straight and catching up on either side, over :data:`EASE_FRAMES` frames each way. Only the
joint's timing changes; the speed maps then re-solve the limb so the foot stays on its target.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from synth_core.build import ik
from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton
from synth_core.quality.metrics import FLIP_MIN_BEND_DEG

Floats = NDArray[np.float64]

# A passage through straight at most this fast (deg per clip frame) is left alone: a shown frame
# that skips one clip frame (rate <= 2) then moves the joint at most 20 deg, short of the 21 deg
# between two bends of 15 deg whose directions are 90 deg apart (a flip, at the least).
CROSS_STEP_DEG = 10.0
EASE_FRAMES = 4.0  # the slowed crossing takes its time from this many frames either side
# A stance's share before its breakover: a passage centred there is left alone (issue 28: hooves
# flat in stance, moving only in the last 20% of it; warped there, a horse's gallop hoof rocked
# 13 mm a frame through its stance).
BREAKOVER_SHARE = 0.2


def bend_vectors(skeleton: Skeleton, rotations: NDArray[np.floating], joint: int, child: int) -> Floats:
    """``(..., 3)``: the bend of ``joint`` (between its parent's bone and its bone to ``child``)
    as a vector in its parent's frame: along the bend axis, its length the angle in degrees.
    It depends on the joint's own local rotation only (bones are rigid)."""
    upper = np.asarray(skeleton.offsets[joint], np.float64)
    upper = upper / max(float(np.linalg.norm(upper)), 1e-12)
    lower = quat.rotate(np.asarray(rotations, np.float64)[..., joint, :],
                        np.asarray(skeleton.offsets[child], np.float64))
    axis = np.cross(np.broadcast_to(upper, lower.shape), lower)
    norm = np.linalg.norm(axis, axis=-1)
    angle = np.degrees(np.arctan2(norm, lower @ upper))
    return np.asarray(axis / np.maximum(norm, 1e-12)[..., None] * angle[..., None])


def _passages(bend: Floats, cyclic: bool) -> tuple[Floats, Floats]:
    """Per frame i: the fastest step (deg a frame) of a passage through straight starting there
    -- the bend's direction reversed (turned more than 90 deg) from frame i to i + 1 or i + 2,
    what a shown frame that skips one clip frame sees -- 0 where none; and the time of the
    passage's closest approach to straight (on the straight line between frames)."""
    F = len(bend)
    idx = np.arange(F)
    at = (lambda k: np.roll(bend, -k, axis=0)) if cyclic else (lambda k: bend[np.minimum(idx + k, F - 1)])
    b1, b2 = at(1), at(2)
    s1, s2 = b1 - bend, b2 - b1
    one = np.sum(bend * b1, axis=-1) < 0
    two = np.sum(bend * b2, axis=-1) < 0
    speed = np.where(one, np.linalg.norm(s1, axis=-1), 0.0)
    speed = np.where(two & ~one, np.maximum(np.linalg.norm(s1, axis=-1), np.linalg.norm(s2, axis=-1)), speed)
    # Closest approach on each of the two steps; the nearer one is the passage's centre.
    tau1 = np.clip(-np.sum(bend * s1, -1) / np.maximum(np.sum(s1 * s1, -1), 1e-12), 0.0, 1.0)
    tau2 = np.clip(-np.sum(b1 * s2, -1) / np.maximum(np.sum(s2 * s2, -1), 1e-12), 0.0, 1.0)
    near1 = np.linalg.norm(bend + tau1[:, None] * s1, axis=-1)
    near2 = np.linalg.norm(b1 + tau2[:, None] * s2, axis=-1)
    centre = np.where(one | (near1 <= near2), idx + tau1, idx + 1 + tau2)
    if not cyclic:
        speed[idx + (1 + (two & ~one)) > F - 1] = 0.0
    return speed, centre


def flat_stance(contacts: NDArray[np.bool_], cyclic: bool,
                breakover: float = BREAKOVER_SHARE) -> NDArray[np.bool_]:
    """``(F, 4)``: frames of each foot's stance before its breakover (the last ``breakover`` of
    the stance), where a foot stands flat."""
    down = np.asarray(contacts, bool)
    F = len(down)
    out = np.zeros_like(down)
    for f in range(down.shape[1]):
        col = down[:, f]
        if col.all():
            out[:, f] = True
            continue
        shift = int(np.argmin(col)) if cyclic else 0  # a run wrapping the loop read from a lift-off
        rolled = np.roll(col, -shift)
        edges = np.flatnonzero(np.diff(np.concatenate([[False], rolled, [False]]).astype(np.int8)))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            keep = int(np.ceil((b - a) * (1.0 - breakover)))
            out[(np.arange(a, a + keep) + shift) % F, f] = True
    return out


def _room(flat: NDArray[np.bool_], tc: float, cyclic: bool) -> tuple[float, float]:
    """How far (frames) a passage centred at ``tc`` is from the flat stance ``flat (F,)`` before
    it and after it (inf: none on that side)."""
    F = len(flat)
    at = np.flatnonzero(flat).astype(np.float64)
    before, after = tc - at, at - tc
    if cyclic:
        before, after = before % F, after % F
    else:
        before, after = before[before >= 0], after[after >= 0]
    return (float(before.min()) if before.size else np.inf), (float(after.min()) if after.size else np.inf)


def _flips(bend: Floats, i: int, cyclic: bool) -> bool:
    """Two of frames ``i``, ``i + 1``, ``i + 2`` bent the two ways, each at least
    metrics.FLIP_MIN_BEND_DEG: a limb flip where they are shown in a row (the second and third
    frames shown one after the other, or the first and third, skipping a clip frame)."""
    F = len(bend)
    rows = [bend[(i + k) % F] if cyclic else bend[min(i + k, F - 1)] for k in range(3)]
    bent = [float(np.linalg.norm(r)) >= FLIP_MIN_BEND_DEG for r in rows]
    return any(bent[a] and bent[b] and rows[a] @ rows[b] < 0 for a, b in ((0, 1), (1, 2), (0, 2)))


def _touchdown(flat: NDArray[np.bool_], i: int, tc: float, cyclic: bool) -> tuple[float, int] | None:
    """For a passage from frame ``i`` in the swing centred at ``tc`` inside the flat stance
    ``flat (F,)`` (both frames around it flat): the stance's first frame and how many swing frames
    lie before it (at most EASE_FRAMES + 1); None for any other passage. The horse's hind
    fetlock, bent 16 deg the frame before its gallop's touchdown, passes through straight over
    the stance's first two frames as the leg sweeps over the hoof: no window fits beside the flat
    stance, and frames shown either side of the touchdown straddle straight."""
    F = len(flat)

    def at(j: int) -> bool:
        return bool(flat[j % F]) if cyclic else 0 <= j < F and bool(flat[j])

    k = int(np.floor(tc))
    if at(i) or not (at(k) and at(k + 1)):
        return None
    for _ in range(F):  # back to the stance's first frame
        if not at(k - 1):
            break
        k -= 1
    room = 0
    while room <= EASE_FRAMES and not at(k - room - 1):  # at() is False off a clip's ends
        room += 1
    return (float(k), room) if room else None


def crossing_times(bend: Floats, cyclic: bool, flat: NDArray[np.bool_] | None = None) -> Floats:
    """``(F,)``: the clip time (fractional frame) each frame shows the joint at, from its bend
    vectors ``(F, 3)``: the identity except around each passage through straight
    (:func:`_passages`) faster than :data:`CROSS_STEP_DEG`, where time is warped
    ``tc + h g((t - tc) / h)``, g(x) = s x + (1 - s) x^3: slope s = CROSS_STEP / step at the
    passage's centre tc, faster on either side, the same at the window's ends. The fastest
    passage first; one whose window would overlap a slowed one keeps its pace. Each side of the
    window (its own h) stops short of ``flat (F,)`` (the foot's stance before breakover:
    :func:`flat_stance`), which keeps its own timing: a passage at a lift-off or a touchdown is
    slowed on its swing side alone (issue 28: a symmetric window left every such passage of the
    real dog's transitions, next to a stance, at 17-24 deg a frame -- flips when played faster).
    A passage centred inside the flat stance but begun in the swing (a fetlock loaded at
    touchdown), that a shown frame skipping one would see as a flip, is eased on its swing side
    alone, toward the touchdown's pose (:func:`_touchdown`)."""
    F = len(bend)
    speed, centre = _passages(bend, cyclic)
    times = np.arange(F, dtype=np.float64)
    taken = np.zeros(F, bool)
    for i in sorted(np.flatnonzero(speed > CROSS_STEP_DEG), key=lambda i: -speed[i]):  # a few per clip
        tc = float(centre[i])
        edge = None
        if flat is not None and flat.any() and _flips(bend, int(i), cyclic):
            edge = _touchdown(flat, int(i), tc, cyclic)
        if edge is not None:  # centred in the flat stance: the swing comes to the touchdown's pose
            tc, room = edge
            h_l, h_r = min(EASE_FRAMES, room), 0.0
        else:
            h_l, h_r = EASE_FRAMES, EASE_FRAMES
            if flat is not None and flat.any():  # each side stops short of the flat stance
                before, after = _room(flat, tc, cyclic)
                h_l, h_r = min(h_l, before), min(h_r, after)
        if not cyclic:
            h_l, h_r = min(h_l, tc), min(h_r, F - 1 - tc)
        t = np.arange(int(np.floor(tc - h_l)) + 1, int(np.ceil(tc + h_r)))
        if (max(h_l, h_r) < 1.0 or (min(h_l, h_r) <= 0.0 and edge is None) or t.size == 0
                or taken[t % F].any()):
            continue
        s = CROSS_STEP_DEG / speed[i]
        h = np.where(t < tc, h_l, h_r)
        x = (t - tc) / h
        times[t % F] = tc + h * (s * x + (1.0 - s) * x**3) - (t - t % F)
        taken[t % F] = True
    return times


def _resampled(q: Floats, times: Floats, cyclic: bool) -> Floats:
    """Unit quaternions ``(F, 4)`` taken at fractional frames ``times`` (nlerp between frames)."""
    F = len(q)
    first = np.floor(times).astype(np.int64)
    w = times - first
    a = first % F if cyclic else np.clip(first, 0, F - 1)
    b = (first + 1) % F if cyclic else np.clip(first + 1, 0, F - 1)
    return np.asarray(quat.nlerp(q[a], q[b], w))


def _paw_joints(rigs: Sequence[ik.LimbRig]) -> tuple[list[tuple[int, int]], list[int]]:
    """Each leg's joints below its hinge (its shin's: a horse's hock or carpus, fetlock and coffin
    joint; a dog's hock or wrist and toe), each with the child its bone points to, and the leg of
    each. The IK keeps their local rotations but the ankle's (whose world orientation it keeps)."""
    joints, legs = [], []
    for leg, rig in enumerate(rigs):
        chain = [*rig.shin, rig.effector]
        joints += list(zip(chain[:-1], chain[1:], strict=True))
        legs += [leg] * (len(chain) - 1)
    return joints, legs


def ease_crossings(skeleton: Skeleton, rotations: NDArray[np.floating],
                   joints: Sequence[tuple[int, int]], cyclic: bool,
                   contacts: NDArray[np.bool_] | None = None,
                   breakover: float = BREAKOVER_SHARE) -> NDArray[np.float32]:
    """Local rotations ``(..., F, J, 4)`` (frames the last leading axis) with each of ``joints``
    (joint, the child its bone points to) passing through straight no faster than
    :data:`CROSS_STEP_DEG` a frame (:func:`crossing_times`). ``cyclic``: the clip loops.
    ``contacts (F, len(joints))``: each joint's foot planted; none is warped in its flat stance
    (:func:`flat_stance`; ``breakover`` 0: in none of its stance)."""
    flat = None if contacts is None else flat_stance(contacts, cyclic, breakover)
    out = np.array(rotations, np.float32)
    F, J = out.shape[-3:-1]
    clips = out.reshape(-1, F, J, 4)  # a speed map's 60, one for a transition
    for k, (joint, child) in enumerate(joints):
        bends = bend_vectors(skeleton, clips, joint, child)
        for n in range(len(clips)):
            times = crossing_times(bends[n], cyclic, None if flat is None else flat[:, k])
            if np.any(times != np.arange(F)):
                clips[n, :, joint] = _resampled(clips[n, :, joint].astype(np.float64), times, cyclic)
    return clips.reshape(out.shape)


def ease_paws(skeleton: Skeleton, rotations: NDArray[np.floating], rigs: Sequence[ik.LimbRig],
              cyclic: bool, contacts: NDArray[np.bool_] | None = None,
              breakover: float = BREAKOVER_SHARE) -> NDArray[np.float32]:
    """:func:`ease_crossings` of every leg's joints below its hinge (:func:`_paw_joints`), each
    kept out of its own foot's flat stance (``contacts (F, 4)``, a column per leg)."""
    joints, legs = _paw_joints(rigs)
    feet = None if contacts is None else contacts[:, legs]
    return ease_crossings(skeleton, rotations, joints, cyclic, feet, breakover)


# A pose -> the root and the toe targets to solve it for.
Placing = Callable[[NDArray[np.floating]], tuple[NDArray[np.floating], NDArray[np.floating]]]


def solve_eased(skeleton: Skeleton, rotations: NDArray[np.floating], place: Placing,
                rigs: tuple[ik.LimbRig, ...], ground: float, axes: NDArray[np.floating],
                cyclic: bool, contacts: NDArray[np.bool_] | None = None
                ) -> tuple[NDArray[np.float32], ik.IKResult, NDArray[np.floating]]:
    """:func:`ik.solve` with flips mended (:func:`ik.mend_flips`), then each paw's joints below
    its hinge (:func:`_paw_joints`: the wrist, hock or toe; a horse's fetlock too) eased through
    straight (:func:`ease_crossings`) and the legs solved again around the paws' new orientation,
    so the feet stay on their targets. ``place``: the root (lowered where a leg would lock straight)
    and the toe targets for a pose -- asked again for the eased one, whose ankles sit elsewhere
    (kept from the first solve, a real dog's gallop locked a fore leg straight). Returns the
    rotations, the last solve's result and its root."""
    root, targets = place(rotations)
    result = ik.solve(skeleton, root, rotations, targets, rigs, ground=ground, axes=axes)
    solved = ik.mend_flips(result.rotations, result.wrong_side, rigs, cyclic=cyclic)
    eased = ease_paws(skeleton, solved, rigs, cyclic, contacts)
    if np.array_equal(eased, solved):  # nothing eased: the first solve stands
        return solved, result, root
    root, targets = place(eased)
    result = ik.solve(skeleton, root, eased, targets, rigs, ground=ground, axes=axes)
    return ik.mend_flips(result.rotations, result.wrong_side, rigs, cyclic=cyclic), result, root
