"""Compiled forward kinematics and limb IK of the render, 16 frames at a time in SIMD lanes.

Pass 1's FK of the joints above the feet and pass 4's limb IK (:func:`synth_core.build.ik.solve`,
without the ground tipping) on the upper joint, hinge and ankle of each leg, then each ankle's bend
side kept from frame to frame, for ``synth_core.compiled.kernels._character``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.build.ik import HINGE_AXIS_MIN_SIN
from synth_core.compiled.jit import render_jit
from synth_core.compiled.vec_kernels import conj, cross, dot3, qmul, qrot, v3, vadd, vscale, vsub
from synth_core.runtime.footlock import LONGEST_OVER, SIDE_DEG

_jit = render_jit
SIDE_TRIES = 3  # see the ankle's side below
_SIDE_TAN2 = math.tan(math.radians(SIDE_DEG)) ** 2

_EPS = 1e-9


# --- limb IK, 16 frames at a time in SIMD lanes -----------------------------------------------
#
# The leg IK is ~700 cycles of dependent scalar arithmetic per leg and frame; written once per
# frame it ran at one frame per instruction (200 ns a leg). Here it runs over a block of frames
# at once with no branch (both candidates computed, one selected), which LLVM vectorizes (8
# frames per AVX-512 instruction, 4x faster). The block is one array allocated in the function
# that loops over it, so every row's address is a known constant offset: with rows of separate
# arrays LLVM cannot rule out that a store overlaps a load and does not vectorize.

# Frames per block, here and in the forward kinematics (whose blocks of world poses the IK
# solves as they are: see :func:`fk`). Two AVX-512 vectors of float64; a short window (a live
# tick's 28 frames) wastes few lanes -- 64 cost live windows 7% more and batches no less.
LANES = 16
# Rows of the block: per frame, the leg's inputs, then its three joints' local rotations.
_P_UP, _P_HI, _P_AN, _P_TOE = 0, 3, 6, 9  # positions, unit space
_R_PUP, _R_UP, _R_HI, _R_PAN, _R_AN, _R_ROOT = 12, 16, 20, 24, 28, 32  # world rotations
_TARGET, _SINK, _OUT, _SIDE, _ROWS = 36, 39, 40, 52, 56  # _SIDE: the ankle's bend after the IK


@_jit()
def _vec3(B: Any, row: int, t: int) -> Any:
    return (B[row, t], B[row + 1, t], B[row + 2, t])


@_jit()
def _quat(B: Any, row: int, t: int) -> Any:
    return (B[row, t], B[row + 1, t], B[row + 2, t], B[row + 3, t])


@_jit()
def _pick3(c: bool, a: Any, b: Any) -> Any:
    return (a[0] if c else b[0], a[1] if c else b[1], a[2] if c else b[2])


@_jit()
def unit4(q: Any) -> Any:
    k = 1.0 / max(math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]), _EPS)
    return (q[0] * k, q[1] * k, q[2] * k, q[3] * k)


@_jit(inline="always")
def _bend(axis: Any, thigh: Any, shin: Any, distance2: float, thigh2: float, shin2: float) -> Any:
    """The hinge's bend (a quaternion, as a 4-tuple) about ``axis`` that makes the hip-to-ankle
    distance squared ``distance2``."""
    # The hinge's turn (ik._turn_to_distance without its trigonometry): a cos + b sin = want;
    # both solutions' cosines and sines follow from a, b and want. The side the axis says
    # first (positive bend about it), then the smaller turn (the larger cosine).
    along = dot3(axis, shin)
    c = dot3(thigh, axis) * along
    a = dot3(thigh, shin) - c
    k = cross(axis, shin)
    b = dot3(thigh, k)
    want = 0.5 * (distance2 - thigh2 - shin2) - c
    amp = math.sqrt(a * a + b * b)
    flat = amp <= _EPS
    inv = 1.0 / max(amp, _EPS)
    cb = 1.0 if flat else a * inv  # cos, sin of the base angle
    sb = 0.0 if flat else b * inv
    cs = min(max(want * inv, -1.0), 1.0)  # cos, sin of the spread either side
    ss = math.sqrt(max(1.0 - cs * cs, 0.0))
    cos1, sin1 = cb * cs + sb * ss, sb * cs - cb * ss
    cos2, sin2 = cb * cs - sb * ss, sb * cs + cb * ss
    turned1 = vadd(vadd(vscale(shin, cos1), vscale(k, sin1)), vscale(axis, along * (1.0 - cos1)))
    turned2 = vadd(vadd(vscale(shin, cos2), vscale(k, sin2)), vscale(axis, along * (1.0 - cos2)))
    rank1 = cos1 + (0.0 if dot3(axis, cross(thigh, turned1)) > 0 else -10.0)
    rank2 = cos2 + (0.0 if dot3(axis, cross(thigh, turned2)) > 0 else -10.0)
    second = rank2 > rank1
    best_cos = cos2 if second else cos1
    half_sin = math.copysign(math.sqrt(max(0.5 * (1.0 - best_cos), 0.0)), sin2 if second else sin1)
    bend_q = vscale(axis, half_sin) + (math.sqrt(max(0.5 * (1.0 + best_cos), 0.0)),)
    return bend_q


@_jit(inline="always")  # into the function allocating B (see the section's comment)
def _solve_block(B: Any, toe_offset: Any, bend: Any, furthest: float) -> None:
    """ik.solve (ground=None) for one leg over the block's LANES frames (rows: see above), its
    ankle put no further than ``furthest`` from the upper joint: toward a target beyond it."""
    for t in range(LANES):
        sink = B[_SINK, t]
        down = (0.0, sink, 0.0)
        p_root = vsub(_vec3(B, _P_UP, t), down)
        p_hinge = vsub(_vec3(B, _P_HI, t), down)
        p_ankle = vsub(_vec3(B, _P_AN, t), down)
        p_toe = vsub(_vec3(B, _P_TOE, t), down)
        ankle_rot = _quat(B, _R_AN, t)
        ankle_target = vsub(_vec3(B, _TARGET, t), qrot(ankle_rot, toe_offset))
        thigh = vsub(p_hinge, p_root)
        shin = vsub(p_ankle, p_hinge)
        # The hinge axis: thigh x shin, else thigh x (toe - hinge), else the leg's dominant
        # axis; turned to the dominant axis's side (ik._hinge_axes). Whether two vectors are
        # HINGE_AXIS_MIN_SIN or more from parallel is asked of their cross product squared, not
        # normalized (seven of ~23 square roots and divisions a frame fewer: the IK ~8% faster).
        to_toe = vsub(p_toe, p_hinge)
        primary = cross(thigh, shin)
        by_toe = cross(thigh, to_toe)
        dominant = qrot(_quat(B, _R_ROOT, t), bend)
        thigh2, shin2 = dot3(thigh, thigh), dot3(shin, shin)
        least = HINGE_AXIS_MIN_SIN * HINGE_AXIS_MIN_SIN * thigh2
        use1 = dot3(primary, primary) >= max(least * shin2, _EPS * _EPS)
        use2 = dot3(by_toe, by_toe) >= max(least * dot3(to_toe, to_toe), _EPS * _EPS)
        pick = _pick3(use1, primary, _pick3(use2, by_toe, dominant))
        size = max(math.sqrt(dot3(pick, pick)), _EPS)
        axis = vscale(pick, math.copysign(1.0 / size, dot3(pick, dominant)))
        to_target = vsub(ankle_target, p_root)
        # The foot lock's limit where its sink (bounded) leaves a target out of it: the leg
        # reaches toward it no further (footlock.LONGEST_OVER), the foot falls short of it.
        distance2 = dot3(to_target, to_target)
        bend_q = _bend(axis, thigh, shin, min(distance2, furthest * furthest), thigh2, shin2)
        # The swing onto the target (quat.between; a half turn where the two are opposite).
        u = vadd(thigh, qrot(bend_q, shin))
        uu = dot3(u, u)
        lengths = math.sqrt(uu * distance2)
        w = lengths + dot3(u, to_target)  # |u||v| (1 + cos): the quaternion, unnormalized
        opposite = w < 1e-9 * max(lengths, _EPS)
        x_ok = abs(u[0]) < 0.9 * math.sqrt(uu)
        half_turn = cross(u, (1.0 if x_ok else 0.0, 0.0 if x_ok else 1.0, 0.0))
        swing = unit4(_pick3(opposite, half_turn, cross(u, to_target)) + (0.0 if opposite else w,))
        upper_world = qmul(swing, _quat(B, _R_UP, t))
        turned = qmul(swing, bend_q)
        hinge_world = qmul(turned, _quat(B, _R_HI, t))
        ankle_parent = qmul(turned, _quat(B, _R_PAN, t))
        q0 = unit4(qmul(conj(_quat(B, _R_PUP, t)), upper_world))
        q1 = unit4(qmul(conj(upper_world), hinge_world))
        q2 = unit4(qmul(conj(ankle_parent), ankle_rot))
        B[_OUT, t], B[_OUT + 1, t], B[_OUT + 2, t], B[_OUT + 3, t] = q0
        B[_OUT + 4, t], B[_OUT + 5, t], B[_OUT + 6, t], B[_OUT + 7, t] = q1
        B[_OUT + 8, t], B[_OUT + 9, t], B[_OUT + 10, t], B[_OUT + 11, t] = q2


# --- forward kinematics, 16 frames at a time in SIMD lanes -----------------------------------
#
# The world poses are kept in blocks of frames, ``world (blocks, 7 J, LANES)``: joint j's
# world rotation in rows 7 j .. 7 j + 3, its position in the next three, frame t in block
# (t - o) // LANES, lane (t - o) % LANES, where the origin o is a frame the caller picks (the
# first frame wanted: a live window's 25 frames are then two blocks of IK, not two or three).
# Each joint (parent order) is then made for a whole block straight from its parent's rows,
# with no branch (8 float64 frames an AVX-512 instruction; frame by frame it was 7 ns a joint,
# now 3.5 with the gathering of the local rotations). Its local rotations are gathered into a
# block of their own first: read from ``rot (T, J, 4)`` in the same loop, LLVM does not
# vectorize it.


@_jit()
def world_position(world: Any, j: int, t: int) -> Any:
    """Joint j's position on frame t - o (the origin: see the section's comment)."""
    b, lane, r = t // LANES, t % LANES, 7 * j + 4
    return (world[b, r, lane], world[b, r + 1, lane], world[b, r + 2, lane])


@_jit()
def fk(rot: Any, root: Any, h: float, parents: Any, offsets: Any, joints: Any, world: Any,
        a: int, T: int, o: int) -> None:
    """World rotations and positions (unit space: root / h) of ``joints`` (parent order) on frames
    ``[a, T)`` of ``rot (T, J, 4)``, into ``world`` from origin ``o`` <= a (see the section's
    comment); a block's lanes outside those frames repeat the nearest one."""
    local = np.empty((4, LANES))
    for b in range((a - o) // LANES, (T - o + LANES - 1) // LANES):
        block = world[b]
        for t in range(LANES):
            u = min(max(o + b * LANES + t, a), T - 1)
            for k in range(4):
                block[k, t] = rot[u, 0, k]
            for k in range(3):
                block[4 + k, t] = root[u, k] / h
        for i in range(1, len(joints)):
            j = joints[i]
            p, q = 7 * parents[j], 7 * j
            offset = v3(offsets[j])
            for t in range(LANES):
                u = min(max(o + b * LANES + t, a), T - 1)
                for k in range(4):
                    local[k, t] = rot[u, j, k]
            for t in range(LANES):
                parent = _quat(block, p, t)
                g = qmul(parent, _quat(local, 0, t))
                x = vadd(_vec3(block, p + 4, t), qrot(parent, offset))
                block[q, t], block[q + 1, t], block[q + 2, t], block[q + 3, t] = g
                block[q + 4, t], block[q + 5, t], block[q + 6, t] = x


@_jit(inline="always")  # into the function allocating B (see the IK section's comment)
def _solve_leg(B: Any, world: Any, targets: Any, sink: Any, rigs: Any, parents: Any, offsets: Any,
               bends: Any, out_rot: Any, f: int, a: int, T: int, o: int, sides: Any, base: int) -> None:
    """Leg f's IK on frames ``[a, T)`` (see :func:`solve_legs`); its ankle's bend after it into
    ``sides[t - base]`` (:func:`_ankle_sides`)."""
    up, hi, an, ef = 7 * rigs[f, 0], 7 * rigs[f, 1], 7 * rigs[f, 2], 7 * rigs[f, 3]
    pup, pan = 7 * parents[rigs[f, 0]], 7 * parents[rigs[f, 2]]
    toe_offset = v3(offsets[rigs[f, 3]])
    bend = v3(bends[f])
    furthest = (1.0 + LONGEST_OVER) * bends[f, 4]  # bends[:, 4]: its longest reach in the poses
    for b in range((a - o) // LANES, (T - o + LANES - 1) // LANES):
        block, b0 = world[b], o + b * LANES
        for t in range(LANES):
            u = min(max(b0 + t, a), T - 1)
            for k in range(3):
                B[_TARGET + k, t] = targets[u, f, k]
            B[_SINK, t] = sink[u]
        for k in range(3):
            for t in range(LANES):
                B[_P_UP + k, t] = block[up + 4 + k, t]
                B[_P_HI + k, t] = block[hi + 4 + k, t]
                B[_P_AN + k, t] = block[an + 4 + k, t]
                B[_P_TOE + k, t] = block[ef + 4 + k, t]
        for k in range(4):
            for t in range(LANES):
                B[_R_PUP + k, t] = block[pup + k, t]
                B[_R_UP + k, t] = block[up + k, t]
                B[_R_HI + k, t] = block[hi + k, t]
                B[_R_PAN + k, t] = block[pan + k, t]
                B[_R_AN + k, t] = block[an + k, t]
                B[_R_ROOT + k, t] = block[k, t]
        _solve_block(B, toe_offset, bend, furthest)
        _ankle_sides(B, v3(offsets[rigs[f, 2]]), toe_offset)
        for t in range(max(a - b0, 0), min(T - b0, LANES)):
            for k in range(4):
                sides[b0 + t - base, k] = B[_SIDE + k, t]
                out_rot[b0 + t, rigs[f, 0], k] = B[_OUT + k, t]
                out_rot[b0 + t, rigs[f, 1], k] = B[_OUT + 4 + k, t]
                out_rot[b0 + t, rigs[f, 2], k] = B[_OUT + 8 + k, t]


@_jit()
def solve_legs(world: Any, targets: Any, sink: Any, rigs: Any, parents: Any, offsets: Any,
               bends: Any, out_rot: Any, a: int, T: int, o: int, before: Any) -> None:
    """Each leg's IK on frames ``[a, T)`` (``world`` from origin ``o``: see :func:`fk`), the root lowered by
    ``sink``: the upper joint's, hinge's and ankle's local rotations of ``out_rot`` replaced, each
    ankle then keeping its bend side from frame to frame (see the section below). Frame a is
    checked against ``before[f] (4, 4)``, leg f's side on frame a - 1 (a live window's last frame
    sent; bent flag 0: none) and, on a flip, straightened (a - 1 is sent already): a low-latency
    window is a frame or two, and its own frames alone kept next to nothing. ``before`` is then set
    to frame T - 1's sides. Solved a block of ``world`` at a time: lanes outside the frames are
    solved too (on the nearest frame's target), not written."""
    B = np.empty((_ROWS, LANES))  # here, not passed in: see the IK section's comment
    sides = np.empty((max(T - a, 1), 4))
    for f in range(4):
        _solve_leg(B, world, targets, sink, rigs, parents, offsets, bends, out_rot, f, a, T, o, sides, a)
        if T > a and _flipped(sides[0], before[f]):  # the frame before is sent: this one goes straight
            _straighten(world, targets, sink, rigs, parents, offsets, bends, out_rot, f, a, o, sides, a)
        for t in range(a + 1, T):
            if _flipped(sides[t - a], sides[t - a - 1]):
                an, ef = rigs[f, 2], rigs[f, 3]
                nearer = _ankle_bend(world, out_rot, offsets, an, ef, t, o)[0] <= \
                    _ankle_bend(world, out_rot, offsets, an, ef, t - 1, o)[0]
                _straighten(world, targets, sink, rigs, parents, offsets, bends, out_rot, f,
                            t if nearer else t - 1, o, sides, a)
        if T > a:
            before[f, :] = sides[T - 1 - a]


@_jit(inline="always")
def _flipped(side: Any, other: Any) -> bool:
    """Whether two frames' ankle sides (:func:`_ankle_sides`' rows), both bent, point apart."""
    turned = side[0] * other[0] + side[1] * other[1] + side[2] * other[2]
    return bool(turned < 0.0 and side[3] > 0.0 and other[3] > 0.0)


# --- the ankle's bend side kept over time ------------------------------------------------------
#
# The IK keeps the paw's world orientation and moves the forearm (shin) above it, so the ankle's
# bend -- forearm to paw: the real dog's wrist, hyperextended in stance and flexed in the swing --
# is whatever the two give. Where the lock holds a paw behind a body running ahead (a transition
# played by distance at 2-3x its clip), the elbow straightens and the forearm leans back over
# the held paw; at lift-off it swings forward again, and the wrist goes from 38 deg one way to
# 35 deg the other in one frame (issue 28's limb flip, the edge suite's: 50 of the real dog's 73
# shown only with the lock). A passage through straight takes frames: where two frames' bends,
# both SIDE_DEG or more, point to opposite sides (in the body's frame, as metrics.limb_flips
# reads them), the one nearer straight has its paw turned in line with the forearm and the leg
# solved again around it (the toe stays on its target) -- the passage goes through straight
# there instead of turning round in one frame. Solved again, the parent bone moves and the paw is no
# longer quite in line: again, up to SIDE_TRIES times, until it is bent less than SIDE_DEG (it then
# has no side, to either neighbour; the real dog's mixed_sizes: a leg locked straight the frame
# before left the wrist 15.9 deg bent after one).


@_jit(inline="always")  # into the function allocating B (see the IK section's comment)
def _ankle_sides(B: Any, upper: Any, lower: Any) -> None:
    """Each lane's ankle bend after the IK, into rows ``_SIDE``: its axis (parent bone ``upper``
    x its bone ``lower``, offsets in their parents' frames) in the root's frame, unnormalized,
    and 1 where it is bent SIDE_DEG or more (a side to keep), else 0. In the lanes, with no
    branch (per frame outside them it cost the render a sixth more): the IK keeps the ankle's
    world rotation, so its parent's is that times its local rotation's inverse."""
    for t in range(LANES):
        local = _quat(B, _OUT + 8, t)
        bone = qrot(local, lower)
        axis = cross(upper, bone)
        along = dot3(upper, bone)
        to_root = qmul(conj(_quat(B, _R_ROOT, t)), _quat(B, _R_AN, t))
        body = qrot(to_root, qrot(conj(local), axis))
        bent = along <= 0.0 or dot3(axis, axis) >= _SIDE_TAN2 * along * along
        B[_SIDE, t], B[_SIDE + 1, t], B[_SIDE + 2, t] = body
        B[_SIDE + 3, t] = 1.0 if bent else 0.0


@_jit()
def _ankle_bend(world: Any, out_rot: Any, offsets: Any, an: int, ef: int, t: int, o: int) -> Any:
    """The ankle's bend on frame t after the IK (deg), and the ankle's world rotation that would
    put it straight (its parent bone kept)."""
    block, lane = world[(t - o) // LANES], (t - o) % LANES
    local = (float(out_rot[t, an, 0]), float(out_rot[t, an, 1]), float(out_rot[t, an, 2]),
             float(out_rot[t, an, 3]))
    upper = v3(offsets[an])
    lower = qrot(local, v3(offsets[ef]))
    along = dot3(upper, lower)
    turn = cross(lower, upper)
    angle = math.degrees(math.atan2(math.sqrt(dot3(turn, turn)), along))
    lengths = math.sqrt(dot3(upper, upper) * dot3(lower, lower))
    parent = qmul(_quat(block, 7 * an, lane), conj(local))
    return angle, qmul(parent, qmul(unit4(turn + (lengths + along,)), local))


@_jit()  # not inlined: rare, and solve_legs' loop stays small
def _straighten(world: Any, targets: Any, sink: Any, rigs: Any, parents: Any, offsets: Any,
                bends: Any, out_rot: Any, f: int, u: int, o: int, sides: Any, base: int) -> None:
    """Leg f's ankle on frame u put in line with its parent bone, the leg solved again around it,
    until it is bent less than SIDE_DEG (at most SIDE_TRIES times): see the section's comment."""
    an = rigs[f, 2]
    block, lane = world[(u - o) // LANES], (u - o) % LANES
    B = np.empty((_ROWS, LANES))  # here, not passed in: see the IK section's comment
    for _ in range(SIDE_TRIES):
        angle, paw = _ankle_bend(world, out_rot, offsets, an, rigs[f, 3], u, o)
        if angle < SIDE_DEG:
            break
        for k in range(4):  # the ankle's world rotation, which the IK keeps
            block[7 * an + k, lane] = paw[k]
        _solve_leg(B, world, targets, sink, rigs, parents, offsets, bends, out_rot, f, u, u + 1, o,
                   sides, base)
