"""Compiled (numba) kernels for the synthesis hot path: pose assembly, warp and foot lock.

The numpy reference is :func:`synth_core.runtime.synthesis.render` with
:func:`synth_core.runtime.footlock.lock_feet`;
this module does the same work, character by character in parallel (``prange``), frame by frame
in registers, so nothing the size of (characters, frames, joints) is made more than once (the
output). Tests hold the two to the same result. Without numba installed, ``AVAILABLE`` is False
and synthesis uses the reference.

One character, in four passes over its frames:

1. blend the plan's table rows (and the piece fading out), turn the root to the heading, put it
   on the path; forward kinematics of the joints above the feet only, in the character's unit
   (its world divided by its scale h: the library skeleton's geometry);
2. plant targets per foot (:func:`synth_core.runtime.footlock.plant_targets`);
3. the root's sink where a target needs a leg straighter than ``REACH`` (eased, bounded);
4. limb IK (:func:`synth_core.build.ik.solve`, without the ground tipping) on the upper joint, hinge
   and ankle of each leg -- 16 frames at a time in SIMD lanes (see the section on it).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

from synth_core import UP_AXIS
from synth_core.build.ik import HINGE_AXIS_MIN_SIN, limb_rigs
from synth_core.compiled.ground_kernels import ground_at
from synth_core.compiled.jit import render_jit
from synth_core.compiled.scratch import Scratch
from synth_core.runtime.footlock import EASE_FRAMES, MAX_SINK, PAD, REACH, TERRAIN_MAX_SINK
from synth_core.runtime.terrain import BUMP_LEAST

if TYPE_CHECKING:
    from synth_core.runtime.bank import Bank
    from synth_core.runtime.plan import Plan
    from synth_core.runtime.terrain import Grounding

try:
    import numba
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; synth_core itself needs only numpy
    AVAILABLE = False

_EPS = 1e-9


F = TypeVar("F", bound=Callable[..., Any])


_jit = render_jit


_prange: Any = numba.prange if AVAILABLE else range


# --- small vector and quaternion helpers (xyzw) on tuples of float64: no allocation per call --

@_jit()
def _qmul(a: Any, b: Any) -> Any:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


@_jit()
def _conj(q: Any) -> Any:
    return (-q[0], -q[1], -q[2], q[3])


@_jit()
def _qrot(q: Any, v: Any) -> Any:
    """q v q*, as quat.rotate: v + w t + u x t with t = 2 u x v."""
    ux, uy, uz, w = q
    tx = 2.0 * (uy * v[2] - uz * v[1])
    ty = 2.0 * (uz * v[0] - ux * v[2])
    tz = 2.0 * (ux * v[1] - uy * v[0])
    return (v[0] + w * tx + (uy * tz - uz * ty), v[1] + w * ty + (uz * tx - ux * tz),
            v[2] + w * tz + (ux * ty - uy * tx))


@_jit()
def _add(a: Any, b: Any) -> Any:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@_jit()
def _sub(a: Any, b: Any) -> Any:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_jit()
def _scale(a: Any, k: float) -> Any:
    return (a[0] * k, a[1] * k, a[2] * k)


@_jit()
def _cross(a: Any, b: Any) -> Any:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@_jit()
def _dot3(a: Any, b: Any) -> float:
    return float(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


@_jit()
def _norm3(a: Any) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@_jit()
def _v3(a: Any) -> Any:
    return (float(a[0]), float(a[1]), float(a[2]))


@_jit()
def _q4(a: Any) -> Any:
    return (float(a[0]), float(a[1]), float(a[2]), float(a[3]))


@_jit()
def _put(out: Any, q: Any) -> None:
    for k in range(len(q)):
        out[k] = q[k]


@_jit()
def _nlerp_into(a: Any, b: Any, w: Any, out: Any) -> None:
    """out = normalize(a (1 - w) + b w sign), b turned to a's side, for the quaternions of a, b
    (float32 ``(4, J)``: components first); w float32. Components first, so the loop over the
    joints reads each component's row in order and LLVM vectorizes it (16 joints an AVX-512
    instruction: 7x faster than xyzw rows, whose interleaved loads it does not). In float32
    throughout: the rows are float32, and mixing in float64 would convert every load."""
    w = np.float32(w)
    keep = np.float32(1.0) - w
    for j in range(a.shape[1]):
        d = a[0, j] * b[0, j] + a[1, j] * b[1, j] + a[2, j] * b[2, j] + a[3, j] * b[3, j]
        s = -w if d < 0 else w
        x = a[0, j] * keep + b[0, j] * s
        y = a[1, j] * keep + b[1, j] * s
        z = a[2, j] * keep + b[2, j] * s
        q = a[3, j] * keep + b[3, j] * s
        n = np.float32(1.0) / np.sqrt(x * x + y * y + z * z + q * q)
        out[0, j], out[1, j], out[2, j], out[3, j] = x * n, y * n, z * n, q * n


# --- the four passes ---------------------------------------------------------------------------

@_jit()
def _assemble(poses: Any, height: Any, surge: Any, rows: Any, weights: Any, yaw: Any, path: Any,
              h: float, out_rot: Any, out_root: Any) -> None:
    """Pass 1 without FK: blended, turned, warped pose of each frame of one character.
    ``poses (K, 4, J)``: the pose table components first (see :func:`_nlerp_into`); the frame is
    blended that way and written out as xyzw rows (``out_rot (T, J, 4)``)."""
    T, J = out_rot.shape[0], out_rot.shape[1]
    before = np.empty((4, J), np.float32)
    now = np.empty((4, J), np.float32)
    pose = np.empty((4, J), np.float32)
    for t in range(T):
        r0, r1, p0, p1 = rows[t, 0], rows[t, 1], rows[t, 2], rows[t, 3]
        w, pw, keep = weights[t, 0], weights[t, 1], weights[t, 2]
        ht = height[r0] * (1 - w) + height[r1] * w
        sg = surge[r0] * (1 - w) + surge[r1] * w
        if keep > 0:
            _nlerp_into(poses[r0], poses[r1], w, now)
            _nlerp_into(poses[p0], poses[p1], pw, before)
            _nlerp_into(now, before, keep, pose)
            ht = ht * (1 - keep) + (height[p0] * (1 - pw) + height[p1] * pw) * keep
            sg = sg * (1 - keep) + (surge[p0] * (1 - pw) + surge[p1] * pw) * keep
        else:
            _nlerp_into(poses[r0], poses[r1], w, pose)
        frame = out_rot[t]
        for j in range(J):
            for k in range(4):
                frame[j, k] = pose[k, j]
        # The heading's half-angle sine and cosine give the whole angle's too (two calls, not four).
        sh, ch = math.sin(0.5 * yaw[t]), math.cos(0.5 * yaw[t])
        _put(frame[0], _qmul((0.0, sh, 0.0, ch), _q4(frame[0])))
        out_root[t, 0] = path[t, 0] + 2.0 * sh * ch * sg * h
        out_root[t, 1] = path[t, 1] + ht * h
        out_root[t, 2] = path[t, 2] + (ch * ch - sh * sh) * sg * h


@_jit()
def _plant_targets(feet: Any, contacts: Any, out: Any) -> None:
    """footlock.plant_targets for one character: feet (T, 4, 3), contacts (T, 4)."""
    T = feet.shape[0]
    avg = np.empty((T, 3))  # per plant, indexed by its first frame
    for f in range(4):
        out[:, f, :] = feet[:, f, :]
        # Plants: average position.
        t = 0
        while t < T:
            if not contacts[t, f]:
                t += 1
                continue
            s = t
            acc0 = acc1 = acc2 = 0.0
            while t < T and contacts[t, f]:
                acc0 += feet[t, f, 0]
                acc1 += feet[t, f, 1]
                acc2 += feet[t, f, 2]
                t += 1
            n = t - s
            avg[s, 0], avg[s, 1], avg[s, 2] = acc0 / n, acc1 / n, acc2 / n
            for u in range(s, t):
                out[u, f, 0], out[u, f, 1], out[u, f, 2] = avg[s, 0], avg[s, 1], avg[s, 2]
        # Swings: eased from the last plant's lift-off correction to the next one's touchdown one.
        t = 0
        last_start = -1
        last_end = -1
        while t < T:
            if contacts[t, f]:
                if t == 0 or not contacts[t - 1, f]:
                    last_start = t
                if t == T - 1 or not contacts[t + 1, f]:
                    last_end = t
                t += 1
                continue
            s = t
            while t < T and not contacts[t, f]:
                t += 1
            has_before = last_start >= 0
            has_after = t < T
            if not (has_before or has_after):
                continue
            for u in range(s, t):
                if has_before and has_after:
                    span = max(t - last_end, 1)
                    x = min(max((u - last_end) / span, 0.0), 1.0)
                    x = x * x * (3 - 2 * x)
                elif has_after:
                    x = 1.0
                else:
                    x = 0.0
                for k in range(3):
                    if k == 1:
                        continue
                    lift = avg[last_start, k] - feet[last_end, f, k] if has_before else 0.0
                    touch = avg[t, k] - feet[t, f, k] if has_after else 0.0
                    out[u, f, k] = feet[u, f, k] + (1 - x) * lift + x * touch


@_jit()
def _ease_sink(sink: Any, limit: float, out: Any) -> None:
    """footlock.ease_sink for one character: running max (EASE_FRAMES, nearest), Gaussian."""
    T = sink.shape[0]
    half = EASE_FRAMES // 2
    spread = np.empty(T)
    for t in range(T):
        m = 0.0
        for u in range(t - half, t - half + EASE_FRAMES):
            m = max(m, min(sink[min(max(u, 0), T - 1)], limit))
        spread[t] = m
    sigma = EASE_FRAMES / 6
    radius = int(4.0 * sigma + 0.5)
    kernel = np.empty(2 * radius + 1)
    total = 0.0
    for i in range(-radius, radius + 1):
        kernel[i + radius] = math.exp(-0.5 * i * i / (sigma * sigma))
        total += kernel[i + radius]
    for t in range(T):
        acc = 0.0
        for i in range(-radius, radius + 1):
            acc += kernel[i + radius] * spread[min(max(t + i, 0), T - 1)]
        out[t] = acc / total


# --- limb IK, 16 frames at a time in SIMD lanes -----------------------------------------------
#
# The leg IK is ~700 cycles of dependent scalar arithmetic per leg and frame; written once per
# frame it ran at one frame per instruction (200 ns a leg). Here it runs over a block of frames
# at once with no branch (both candidates computed, one selected), which LLVM vectorizes (8
# frames per AVX-512 instruction, 4x faster). The block is one array allocated in the function
# that loops over it, so every row's address is a known constant offset: with rows of separate
# arrays LLVM cannot rule out that a store overlaps a load and does not vectorize.

# Frames per block, here and in the forward kinematics (whose blocks of world poses the IK
# solves as they are: see :func:`_fk`). Two AVX-512 vectors of float64; a short window (a live
# tick's 28 frames) wastes few lanes -- 64 cost live windows 7% more and batches no less.
LANES = 16
# Rows of the block: per frame, the leg's inputs, then its three joints' local rotations.
_P_UP, _P_HI, _P_AN, _P_TOE = 0, 3, 6, 9  # positions, unit space
_R_PUP, _R_UP, _R_HI, _R_PAN, _R_AN, _R_ROOT = 12, 16, 20, 24, 28, 32  # world rotations
_TARGET, _SINK, _OUT, _ROWS = 36, 39, 40, 52


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
def _unit4(q: Any) -> Any:
    k = 1.0 / max(math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]), _EPS)
    return (q[0] * k, q[1] * k, q[2] * k, q[3] * k)


@_jit(inline="always")  # into the function allocating B (see the section's comment)
def _solve_block(B: Any, toe_offset: Any, bend: Any) -> None:
    """ik.solve (ground=None) for one leg over the block's LANES frames (rows: see above)."""
    for t in range(LANES):
        sink = B[_SINK, t]
        down = (0.0, sink, 0.0)
        p_root = _sub(_vec3(B, _P_UP, t), down)
        p_hinge = _sub(_vec3(B, _P_HI, t), down)
        p_ankle = _sub(_vec3(B, _P_AN, t), down)
        p_toe = _sub(_vec3(B, _P_TOE, t), down)
        ankle_rot = _quat(B, _R_AN, t)
        ankle_target = _sub(_vec3(B, _TARGET, t), _qrot(ankle_rot, toe_offset))
        thigh = _sub(p_hinge, p_root)
        shin = _sub(p_ankle, p_hinge)
        # The hinge axis: thigh x shin, else thigh x (toe - hinge), else the leg's dominant
        # axis; turned to the dominant axis's side (ik._hinge_axes). Whether two vectors are
        # HINGE_AXIS_MIN_SIN or more from parallel is asked of their cross product squared, not
        # normalized (seven of ~23 square roots and divisions a frame fewer: the IK ~8% faster).
        to_toe = _sub(p_toe, p_hinge)
        primary = _cross(thigh, shin)
        by_toe = _cross(thigh, to_toe)
        dominant = _qrot(_quat(B, _R_ROOT, t), bend)
        thigh2, shin2 = _dot3(thigh, thigh), _dot3(shin, shin)
        least = HINGE_AXIS_MIN_SIN * HINGE_AXIS_MIN_SIN * thigh2
        use1 = _dot3(primary, primary) >= max(least * shin2, _EPS * _EPS)
        use2 = _dot3(by_toe, by_toe) >= max(least * _dot3(to_toe, to_toe), _EPS * _EPS)
        pick = _pick3(use1, primary, _pick3(use2, by_toe, dominant))
        size = max(math.sqrt(_dot3(pick, pick)), _EPS)
        axis = _scale(pick, math.copysign(1.0 / size, _dot3(pick, dominant)))
        to_target = _sub(ankle_target, p_root)
        distance2 = _dot3(to_target, to_target)
        # The hinge's turn (ik._turn_to_distance without its trigonometry): a cos + b sin = want;
        # both solutions' cosines and sines follow from a, b and want. The side the axis says
        # first (positive bend about it), then the smaller turn (the larger cosine).
        along = _dot3(axis, shin)
        c = _dot3(thigh, axis) * along
        a = _dot3(thigh, shin) - c
        k = _cross(axis, shin)
        b = _dot3(thigh, k)
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
        turned1 = _add(_add(_scale(shin, cos1), _scale(k, sin1)), _scale(axis, along * (1.0 - cos1)))
        turned2 = _add(_add(_scale(shin, cos2), _scale(k, sin2)), _scale(axis, along * (1.0 - cos2)))
        rank1 = cos1 + (0.0 if _dot3(axis, _cross(thigh, turned1)) > 0 else -10.0)
        rank2 = cos2 + (0.0 if _dot3(axis, _cross(thigh, turned2)) > 0 else -10.0)
        second = rank2 > rank1
        best_cos = cos2 if second else cos1
        half_sin = math.copysign(math.sqrt(max(0.5 * (1.0 - best_cos), 0.0)), sin2 if second else sin1)
        bend_q = _scale(axis, half_sin) + (math.sqrt(max(0.5 * (1.0 + best_cos), 0.0)),)
        # The swing onto the target (quat.between; a half turn where the two are opposite).
        u = _add(thigh, _qrot(bend_q, shin))
        uu = _dot3(u, u)
        lengths = math.sqrt(uu * distance2)
        w = lengths + _dot3(u, to_target)  # |u||v| (1 + cos): the quaternion, unnormalized
        opposite = w < 1e-9 * max(lengths, _EPS)
        x_ok = abs(u[0]) < 0.9 * math.sqrt(uu)
        half_turn = _cross(u, (1.0 if x_ok else 0.0, 0.0 if x_ok else 1.0, 0.0))
        swing = _unit4(_pick3(opposite, half_turn, _cross(u, to_target)) + (0.0 if opposite else w,))
        upper_world = _qmul(swing, _quat(B, _R_UP, t))
        turned = _qmul(swing, bend_q)
        hinge_world = _qmul(turned, _quat(B, _R_HI, t))
        ankle_parent = _qmul(turned, _quat(B, _R_PAN, t))
        q0 = _unit4(_qmul(_conj(_quat(B, _R_PUP, t)), upper_world))
        q1 = _unit4(_qmul(_conj(upper_world), hinge_world))
        q2 = _unit4(_qmul(_conj(ankle_parent), ankle_rot))
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
def _world_position(world: Any, j: int, t: int) -> Any:
    """Joint j's position on frame t - o (the origin: see the section's comment)."""
    b, lane, r = t // LANES, t % LANES, 7 * j + 4
    return (world[b, r, lane], world[b, r + 1, lane], world[b, r + 2, lane])


@_jit()
def _fk(rot: Any, root: Any, h: float, parents: Any, offsets: Any, joints: Any, world: Any,
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
            offset = _v3(offsets[j])
            for t in range(LANES):
                u = min(max(o + b * LANES + t, a), T - 1)
                for k in range(4):
                    local[k, t] = rot[u, j, k]
            for t in range(LANES):
                parent = _quat(block, p, t)
                g = _qmul(parent, _quat(local, 0, t))
                x = _add(_vec3(block, p + 4, t), _qrot(parent, offset))
                block[q, t], block[q + 1, t], block[q + 2, t], block[q + 3, t] = g
                block[q + 4, t], block[q + 5, t], block[q + 6, t] = x


@_jit()
def _solve_legs(world: Any, targets: Any, sink: Any, rigs: Any, parents: Any, offsets: Any,
                bends: Any, out_rot: Any, a: int, T: int, o: int) -> None:
    """Each leg's IK on frames ``[a, T)`` (``world`` from origin ``o``: see :func:`_fk`), the root lowered by
    ``sink``: the upper joint's, hinge's and ankle's local rotations of ``out_rot`` replaced.
    Solved a block of ``world`` at a time: lanes outside the frames are solved too (on the
    nearest frame's target), not written."""
    B = np.empty((_ROWS, LANES))  # here, not passed in: see the section's comment
    for f in range(4):
        up, hi, an, ef = 7 * rigs[f, 0], 7 * rigs[f, 1], 7 * rigs[f, 2], 7 * rigs[f, 3]
        pup, pan = 7 * parents[rigs[f, 0]], 7 * parents[rigs[f, 2]]
        toe_offset = _v3(offsets[rigs[f, 3]])
        bend = _v3(bends[f])
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
            _solve_block(B, toe_offset, bend)
            for t in range(max(a - b0, 0), min(T - b0, LANES)):
                for k in range(4):
                    out_rot[b0 + t, rigs[f, 0], k] = B[_OUT + k, t]
                    out_rot[b0 + t, rigs[f, 1], k] = B[_OUT + 4 + k, t]
                    out_rot[b0 + t, rigs[f, 2], k] = B[_OUT + 8 + k, t]


# What the sink of a frame reads of its pose, per foot (see :func:`_character`): the ankle-to-toe
# vector, the upper joint's position and the leg's reach. A live window keeps them for its last
# PAD frames, whose sink the next window's first frames read: those are then not posed again.
_LEG_TOE, _LEG_UP, _LEG_REACH = 0, 3, 6
LEG_WIDTH = 7
NOWHERE = -(1 << 62)  # Posed.legs_at of a character whose last window kept no legs


@_jit()
def _swing_share(targets: Any, f: int, last: int, u: int, nxt: int) -> float:
    """terrain.swing_share of frame u of a swing from plant frame ``last`` to ``nxt``."""
    gone = math.hypot(targets[u, f, 0] - targets[last, f, 0], targets[u, f, 2] - targets[last, f, 2])
    left = math.hypot(targets[nxt, f, 0] - targets[u, f, 0], targets[nxt, f, 2] - targets[u, f, 2])
    if gone + left > 1e-9:
        return float(gone / (gone + left))
    return float((u - last) / (nxt - last))


@_jit()
def _ground_targets(targets: Any, contacts: Any, heights: Any, x0: float, z0: float, spacing: float,
                    h: float, under: Any) -> None:
    """terrain.ground_targets for one character, in place (``under (T,)``: scratch)."""
    T = targets.shape[0]
    for f in range(4):
        for t in range(T):
            under[t] = ground_at(heights, x0, z0, spacing, targets[t, f, 0] * h, targets[t, f, 2] * h) / h
        t = 0
        while t < T:
            if contacts[t, f]:
                targets[t, f, 1] = max(targets[t, f, 1], 0.0) + under[t]
                t += 1
                continue
            s = t
            while t < T and not contacts[t, f]:
                t += 1
            last, nxt = s - 1, t
            if last < 0 or nxt >= T:  # no plant before or after it: the terrain under it
                for u in range(s, t):
                    targets[u, f, 1] = max(targets[u, f, 1], 0.0) + under[u]
                continue
            lift = 0.0
            for u in range(s, t):
                x = _swing_share(targets, f, last, u, nxt)
                e = under[last] + (under[nxt] - under[last]) * x
                lift = max(lift, (under[u] - e) / max(4.0 * x * (1.0 - x), BUMP_LEAST))
            for u in range(s, t):
                x = _swing_share(targets, f, last, u, nxt)
                e = under[last] + (under[nxt] - under[last]) * x
                targets[u, f, 1] = max(targets[u, f, 1], 0.0) + max(e + lift * 4.0 * x * (1.0 - x), under[u])


@_jit()
def _character(poses: Any, height: Any, surge: Any, rows: Any, weights: Any, yaw: Any, path: Any,
                    h: float, contacts: Any, parents: Any, offsets: Any, fk_joints: Any, rigs: Any,
                    bends: Any, sink_limit: float, foot_lock: bool, out_rot: Any, out_root: Any,
                    world: Any, feet: Any, legs: Any, targets: Any, sink: Any, eased: Any,
                    keep_from: int, keep_to: int, known_feet: Any, known: int, recent: Any,
                    recent_known: bool, tilt: Any, tilt_at: int, heights: Any, ground_x0: float,
                    ground_z0: float, spacing: float) -> bool:
    """All four passes for one character (scratch arrays given). Only frames ``[keep_from,
    keep_to)`` are wanted (a window rendered over its foot lock's context): the legs' IK, which
    reads nothing of other frames, is solved for those alone.

    ``known_feet (T, 4, 3)``: the feet of frames ``[0, known)`` made already (a live session's
    earlier windows), read there, not posed again, and written for the frames posed (an empty
    array: none kept). ``recent (PAD, 4, LEG_WIDTH)``: what the sink reads of the PAD frames
    before ``keep_from``, if ``recent_known`` (then ``known >= keep_from``): those are not posed
    either. On return it holds the same of the PAD frames before ``keep_to``: True if it does
    (the first frames of a plan have fewer than PAD frames before them).

    ``heights (Nz, Nx)``: the terrain (``(0, 0)``: none), its grid's origin and spacing; the body
    then tilted by ``tilt[tilt_at + t]`` (``(T', 4)``) on frame t and its feet planted on the
    terrain (:mod:`synth_core.runtime.terrain`)."""
    terrain = heights.shape[0] > 0
    T = out_rot.shape[0]
    if not foot_lock:
        keep_from, keep_to, known, recent_known = 0, T, 0, False  # no context
    # Posed from a; the sink from s, the first frame the wanted frames' eased sink reads.
    if recent_known:
        s, a = keep_from - PAD, keep_from
        legs[s:a] = recent
    else:
        s = a = max(min(known, keep_from - PAD), 0)
    _assemble(poses, height, surge, rows[a:], weights[a:], yaw[a:], path[a:], h, out_rot[a:], out_root[a:])
    if terrain:
        for t in range(a, T):
            _put(out_rot[t, 0], _qmul(_q4(tilt[tilt_at + t]), _q4(out_rot[t, 0])))
    if not foot_lock:
        return False
    # The world's origin: a block starts at the first wanted frame (the frames posed before it
    # in blocks of their own), so a window of up to LANES frames is one block of IK.
    o = keep_from - LANES * ((keep_from - a + LANES - 1) // LANES)
    _fk(out_rot, out_root, h, parents, offsets, fk_joints, world, a, T, o)
    feet[:a] = known_feet[:a]
    for t in range(a, T):
        for f in range(4):
            up, hi, an, ef = rigs[f, 0], rigs[f, 1], rigs[f, 2], rigs[f, 3]
            p_up, p_hi = _world_position(world, up, t - o), _world_position(world, hi, t - o)
            p_an, p_ef = _world_position(world, an, t - o), _world_position(world, ef, t - o)
            if terrain:  # as the leg hangs untilted, above the body's ground (terrain.untilt)
                r = _scale(_v3(out_root[t]), 1.0 / h)
                q = _q4(tilt[tilt_at + t])
                p = _add(r, _qrot(_conj(_unit4((q[0], q[1], q[2], q[3] + 1.0))), _sub(p_ef, r)))
                y = r[1] + _qrot(_conj(q), _sub(p_ef, r))[1]
                feet[t, f, 0], feet[t, f, 1], feet[t, f, 2] = p[0], y - path[t, 1] / h, p[2]
            else:
                feet[t, f, 0], feet[t, f, 1], feet[t, f, 2] = p_ef
            leg = legs[t, f]
            leg[_LEG_TOE], leg[_LEG_TOE + 1], leg[_LEG_TOE + 2] = _sub(p_ef, p_an)
            leg[_LEG_UP], leg[_LEG_UP + 1], leg[_LEG_UP + 2] = p_up
            leg[_LEG_REACH] = _norm3(_sub(p_hi, p_up)) + _norm3(_sub(p_an, p_hi))
    if known_feet.shape[0] > 0:
        known_feet[a:] = feet[a:]
    _plant_targets(feet, contacts, targets)
    if terrain:
        _ground_targets(targets, contacts, heights, ground_x0, ground_z0, spacing, h, sink)
    for t in range(s, T):
        floor = path[t, 1] / h
        worst = 0.0
        for f in range(4):
            if not terrain and targets[t, f, 1] < floor:
                targets[t, f, 1] = floor
            leg = legs[t, f]
            to_ankle = _sub(_sub(_v3(targets[t, f]), _v3(leg[_LEG_TOE:])), _v3(leg[_LEG_UP:]))
            allowed = REACH * leg[_LEG_REACH]
            across2 = to_ankle[0] ** 2 + to_ankle[2] ** 2
            worst = max(worst, -to_ankle[1] - math.sqrt(max(allowed * allowed - across2, 0.0)))
        sink[t] = worst
    # Eased from frame s on: the wanted frames, PAD or more after it, read nothing before it.
    _ease_sink(sink[s:], sink_limit, eased[s:])
    for t in range(a, T):
        out_root[t, 1] = (out_root[t, 1] / h - eased[t]) * h
    _solve_legs(world, targets, eased, rigs, parents, offsets, bends, out_rot, keep_from, keep_to, o)
    if keep_to - PAD < s:
        return False
    recent[...] = legs[keep_to - PAD:keep_to]
    return True


@_jit(parallel=True)
def _render_all(poses: Any, height: Any, surge: Any, rows: Any, weights: Any, yaw: Any, path: Any,
                scales: Any, contacts: Any, parents: Any, offsets: Any, fk_joints: Any, rigs: Any,
                bends: Any, sink_limit: float, foot_lock: bool, out_rot: Any, out_root: Any,
                w_world: Any, w_feet: Any, w_legs: Any, w_targets: Any, w_sink: Any, w_eased: Any,
                tilt: Any, heights: Any, ground_x0: float, ground_z0: float, spacing: float) -> None:
    """``w_*``: one working set per worker (first axis), reused for its characters: a fresh
    megabyte per character would cost more in page faults than the lock's arithmetic."""
    C = out_rot.shape[0]
    workers = min(C, w_world.shape[0])
    none_known = np.empty((0, 4, 3))
    for worker in _prange(workers):
        world, feet, legs, targets = w_world[worker], w_feet[worker], w_legs[worker], w_targets[worker]
        sink, eased = w_sink[worker], w_eased[worker]
        recent = np.empty((PAD, 4, LEG_WIDTH))
        for c in range(worker, C, workers):
            own_tilt = tilt[c] if heights.shape[0] > 0 else tilt[0]
            _character(poses, height, surge, rows[c], weights[c], yaw[c], path[c], scales[c],
                       contacts[c], parents, offsets, fk_joints, rigs, bends, sink_limit, foot_lock,
                       out_rot[c], out_root[c], world, feet, legs, targets, sink, eased, 0,
                       out_rot.shape[1], none_known, 0, recent, False, own_tilt, 0, heights, ground_x0,
                       ground_z0, spacing)


@_jit(parallel=True)
def _render_windows(poses: Any, height: Any, surge: Any, rows: Any, weights: Any, yaw: Any, path: Any,
                    scales: Any, contacts: Any, parents: Any, offsets: Any, fk_joints: Any, rigs: Any,
                    bends: Any, sink_limit: float, foot_lock: bool, workers: int, begin: Any, end: Any,
                    start: int, out_rot: Any, out_root: Any, tilt: Any, heights: Any, ground_x0: float,
                    ground_z0: float, spacing: float, known_feet: Any, known: Any,
                    known_legs: Any, legs_at: Any, c0: int, c1: int) -> None:
    """Frames ``[start, start + out.shape[1])`` of characters ``[c0, c1)``, each rendered over
    its own context ``[begin[c], end[c])`` of the plan (see :func:`render_window`);
    ``known_feet (T, C, 4, 3)`` (or none: ``(0, C, 4, 3)``), ``known``, ``known_legs``,
    ``legs_at``: a :class:`Posed`'s, moved on (``known`` to ``end``, ``legs_at`` to the
    window's end). Calls for disjoint character ranges may run side by side."""
    n, J = out_rot.shape[1], out_rot.shape[2]
    longest = 0
    for c in range(c0, c1):
        longest = max(longest, end[c] - begin[c])
    workers = min(c1 - c0, workers)
    keep = known_feet.shape[0] > 0
    for worker in _prange(workers):
        rot = np.empty((longest, J, 4), np.float32)
        root = np.empty((longest, 3))
        # See _fk: from an origin up to LANES - 1 frames before the first posed.
        world = np.empty(((longest + 2 * LANES - 2) // LANES, 7 * J, LANES))
        feet = np.empty((longest, 4, 3))
        legs = np.empty((longest, 4, LEG_WIDTH))
        targets = np.empty((longest, 4, 3))
        sink = np.empty(longest)
        eased = np.empty(longest)
        no_recent = np.empty((PAD, 4, LEG_WIDTH))
        for c in range(c0 + worker, c1, workers):
            b, e = begin[c], end[c]
            k = e - b
            kn = min(max(known[c] - b, 0), k) if keep else 0  # frames with their feet known
            recent_known = keep and legs_at[c] == start and start - b >= PAD and kn >= start - b
            own_tilt = tilt[c] if heights.shape[0] > 0 else tilt[0]
            own_legs = known_legs[c] if keep else no_recent
            made = _character(poses, height, surge, rows[c, b:e], weights[c, b:e], yaw[c, b:e],
                              path[c, b:e], scales[c], contacts[c, b:e], parents, offsets, fk_joints, rigs,
                              bends, sink_limit, foot_lock, rot[:k], root[:k], world, feet[:k], legs[:k],
                              targets[:k], sink[:k], eased[:k], start - b, start - b + n,
                              known_feet[b:e, c], kn, own_legs, recent_known,
                              own_tilt, b, heights, ground_x0,
                              ground_z0, spacing)
            out_rot[c] = rot[start - b:start - b + n]
            out_root[c] = root[start - b:start - b + n]
            if keep and foot_lock:
                legs_at[c] = start + n if made else NOWHERE
                if known[c] >= b:  # frames [0, e) known now (else a gap before b)
                    known[c] = max(known[c], e)


@_jit()
def _run_start(flags: Any, t: int) -> int:
    """The first frame of the run of equal flags that frame t is in."""
    while t > 0 and flags[t - 1] == flags[t]:
        t -= 1
    return t


@_jit()
def _run_end(flags: Any, t: int) -> int:
    """The frame after the last of the run of equal flags that frame t is in."""
    T = len(flags)
    while t + 1 < T and flags[t + 1] == flags[t]:
        t += 1
    return t + 1


@_jit()
def _lock_contexts(contacts: Any, start: int, stop: int, pad: int, begin: Any, end: Any) -> None:
    C, T, F = contacts.shape
    lo, hi = max(start - pad, 0), min(stop + pad, T)
    for c in range(C):
        b, e = T, 0
        for f in range(F):
            flags = contacts[c, :, f]
            run = _run_start(flags, lo)  # the plant lo is in, or the plant before its swing
            b = min(b, run if flags[lo] else (_run_start(flags, run - 1) if run > 0 else 0))
            after = _run_end(flags, hi - 1)  # the plant hi - 1 is in, or the plant after its swing
            e = max(e, after if flags[hi - 1] else (_run_end(flags, after) if after < T else T))
        begin[c], end[c] = b, e


def lock_context(contacts: NDArray[np.bool_], start: int, stop: int
                 ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """:func:`synth_core.runtime.streaming.lock_context`, compiled: a scan from the window's ends over
    the runs each foot is in, instead of every frame's run bounds (a live session's every
    window spent 20 ms per 4,000 characters on those)."""
    C = contacts.shape[0]
    begin, end = np.empty(C, np.int64), np.empty(C, np.int64)
    _lock_contexts(contacts, start, stop, PAD, begin, end)
    return begin, end


def _terrain_arrays(ground: Grounding | None) -> tuple[Any, Any, float, float, float]:
    """tilt, heights, grid origin x and z, spacing; no terrain: empty arrays (one layout each,
    so the kernels are compiled once for both)."""
    if ground is None:
        return np.empty((1, 0, 4)), np.empty((0, 0)), 0.0, 0.0, 1.0
    f = ground.field
    return (np.ascontiguousarray(ground.tilt, np.float64), np.ascontiguousarray(f.heights, np.float64),
            f.origin[0], f.origin[1], f.spacing)


def _plan_arrays(plan: Plan) -> tuple[Any, Any, Any, Any, Any, Any]:
    """rows, weights, yaw, path, scales, contacts: C-contiguous, whatever view the plan holds.

    One memory layout, so each kernel is compiled once: numba compiles a view ('A' layout) and a
    contiguous array ('C') separately, and fastmath code for the two may round differently --
    a window of a batch would then differ from the whole in the last bits."""
    c = np.ascontiguousarray
    return (c(plan.rows), c(plan.weights), c(plan.yaw), c(plan.path), c(plan.scales, np.float64),
            c(plan.contacts))


@functools.lru_cache(maxsize=8)
def _bank_tables(bank: Bank) -> tuple[tuple[Any, Any, Any], tuple[Any, Any, Any, Any, Any, float]]:
    """The bank's arrays as the kernels take them (made once per bank: a small batch's call
    would otherwise spend a third of its time here): (pose table, heights, surges) and (parents,
    offsets, the joints above the feet (FK needs no others), the legs' rig table, bend axes,
    the sink limit)."""
    sk = bank.skeleton
    rigs = limb_rigs(sk)
    rig_table = np.array([[r.upper, r.hinge, r.ankle, r.effector] for r in rigs], np.int64)
    needed = np.zeros(sk.n_joints, bool)
    for r in rigs:
        j = r.effector
        while j >= 0:
            needed[j] = True
            j = int(sk.parents[j])
    poses = np.ascontiguousarray(bank.poses.transpose(0, 2, 1))  # components first: see _nlerp_into
    return ((poses, bank.height.astype(np.float64), bank.surge.astype(np.float64)),
            (sk.parents.astype(np.int64), sk.offsets.astype(np.float64),
             np.flatnonzero(needed).astype(np.int64), rig_table, np.asarray(bank.bends, np.float64),
             MAX_SINK * sk.leg_length()))


def _sink_limit(bank: Bank, ground: Grounding | None
                ) -> tuple[tuple[Any, Any, Any], tuple[Any, Any, Any, Any, Any, float]]:
    """:func:`_bank_tables`, the sink limit that on a terrain (footlock.TERRAIN_MAX_SINK)."""
    table, skeleton = _bank_tables(bank)
    if ground is None:
        return table, skeleton
    return table, (*skeleton[:5], TERRAIN_MAX_SINK * bank.skeleton.leg_length())


# Parts of a shared window's characters (see render_window): enough that a thread done with its own
# work takes a part of another's and the two end near together, few enough that each call's
# overhead stays small.
SHARED_PARTS = 8


class Posed(NamedTuple):
    """What a live session's windows keep of the frames they posed, for the later windows over
    the same plan (see :func:`render_window`): the feet ``(T, C, 4, 3)`` float64, C-contiguous
    (frames first: every view of them is, so the kernel is compiled for one layout), of each
    character's plan frames ``[0, frames[c])``; what the sink reads of the legs on the PAD
    frames before ``legs_at[c]`` (``(C, PAD, 4, LEG_WIDTH)``; ``NOWHERE``: none kept)."""

    feet: NDArray[np.float64]
    frames: NDArray[np.int64]
    legs: NDArray[np.float64]
    legs_at: NDArray[np.int64]

    @classmethod
    def none(cls, C: int, feet: NDArray[np.float64]) -> Posed:
        """Nothing posed yet, the feet to be kept in ``feet``."""
        return cls(feet, np.zeros(C, np.int64), np.empty((C, PAD, 4, LEG_WIDTH)), np.full(C, NOWHERE))


def render_window(bank: Bank, plan: Plan, start: int, stop: int, begin: NDArray[np.int64],
                  end: NDArray[np.int64], foot_lock: bool = True, known: Posed | None = None,
                  out: NDArray[np.float32] | None = None,
                  share: Callable[[list[Callable[[], None]]], None] | None = None,
                  ground: Grounding | None = None) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Root ``(C, stop - start, 3)`` and rotations of frames ``[start, stop)`` only, each
    character rendered over its context ``[begin, end)`` of ``plan`` (from
    :func:`synth_core.runtime.streaming.lock_context`): the same numbers as :func:`render` of the whole
    (with ``known``: to rounding, see tests/test_live.py).

    ``known``: what earlier windows over the same plan posed (a live session's windows share
    most of their context: posing it again was two-fifths of their render). Frames whose feet
    are known are not posed again but where wanted; nor, after a window that ended at ``start``,
    the PAD frames before it (their sink read from ``known.legs``: a third of the posing left).
    What the frames posed give is written there, ``frames`` and ``legs_at`` moved on.

    ``out``: the rotations are written there (C-contiguous ``(C, stop - start, J, 4)`` float32).

    ``share``: the characters are cut into SHARED_PARTS parts, each a one-thread render, which
    ``share`` runs (:func:`synth_core.compiled.render_pool.shared`: threads with nothing else to do take
    some): renders side by side on the pool's threads -- a live session's shards, a stream's
    first-window parts -- finish together though one has more to pose than the other.

    ``ground``: the plan stands on a terrain (:func:`synth_core.runtime.terrain.ground_plan`)."""
    if not AVAILABLE:
        raise RuntimeError("synth_core.compiled.kernels needs numba; use the numpy backend")
    C = plan.yaw.shape[0]
    J = bank.skeleton.n_joints
    # Only the frames some context reads are made contiguous.
    cb, ce = int(np.min(begin)), int(np.max(end))
    posed = Posed(np.empty((0, C, 4, 3)), np.zeros(C, np.int64), np.empty((0, PAD, 4, LEG_WIDTH)),
                  np.zeros(C, np.int64)) if known is None else known
    if known is not None:
        feet = known.feet
        assert feet.shape == (*plan.yaw.shape[::-1], 4, 3) and feet.dtype == np.float64
        assert feet.flags.c_contiguous
        assert known.legs.shape == (C, PAD, 4, LEG_WIDTH) and known.legs.flags.c_contiguous
        for frames in (known.frames, known.legs_at):
            assert frames.dtype == np.int64 and frames.flags.c_contiguous
    # In the window's frames (moved back after).
    posed.frames[...] -= cb
    posed.legs_at[...] -= cb
    out_root = np.empty((C, stop - start, 3), np.float64)
    out_rot = np.empty((C, stop - start, J, 4), np.float32) if out is None else out
    assert out_rot.shape == (C, stop - start, J, 4) and out_rot.dtype == np.float32
    assert out_rot.flags.c_contiguous
    table, skeleton = _sink_limit(bank, ground)
    args = (*table, *_plan_arrays(plan.window(cb, ce)), *skeleton, foot_lock,
            1 if share else numba.get_num_threads(), np.asarray(begin, np.int64) - cb,
            np.asarray(end, np.int64) - cb, start - cb, out_rot, out_root,
            *_terrain_arrays(None if ground is None else ground.window(cb, ce)),
            posed.feet[cb:ce] if known is not None else posed.feet, posed.frames, posed.legs, posed.legs_at)
    try:
        if share is None:
            _render_windows(*args, 0, C)
        else:
            cuts = np.linspace(0, C, SHARED_PARTS + 1).round().astype(np.int64).tolist()
            share([functools.partial(_render_windows, *args, a, b)
                   for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a])
    finally:
        posed.frames[...] += cb
        posed.legs_at[...] += cb
    return out_root.astype(np.float32), out_rot


def render(bank: Bank, plan: Plan, foot_lock: bool = True,
           out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
           scratch: Scratch | None = None, ground: Grounding | None = None
           ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Root ``(C, T, 3)`` and local rotations ``(C, T, J, 4)`` of a plan (see
    :func:`synth_core.runtime.synthesis.render`, the reference); into ``out`` (root, rotations) if given.
    ``scratch``: where the workers' working sets are kept between calls (a small chunk's call
    would otherwise spend a fifth of its time faulting them in). ``ground``: the plan stands on
    a terrain (:func:`synth_core.runtime.terrain.ground_plan`)."""
    if not AVAILABLE:
        raise RuntimeError("synth_core.compiled.kernels needs numba; use the numpy backend")
    C, T = plan.yaw.shape
    J = bank.skeleton.n_joints
    W = min(C, numba.get_num_threads())
    scratch = Scratch() if scratch is None else scratch
    work = [scratch.array(f"render.{name}", shape, np.float64)
            for name, shape in (("world", (W, -(-T // LANES), 7 * J, LANES)), ("feet", (W, T, 4, 3)),
                                ("legs", (W, T, 4, LEG_WIDTH)),
                                ("targets", (W, T, 4, 3)), ("sink", (W, T)), ("eased", (W, T)),
                                ("root", (C, T, 3)))]
    out_root = work.pop()
    out_rot = np.empty((C, T, J, 4), np.float32) if out is None else out[1]
    table, skeleton = _sink_limit(bank, ground)
    w_world, w_feet, w_legs, w_targets, w_sink, w_eased = work
    _render_all(*table, *_plan_arrays(plan), *skeleton, foot_lock, out_rot, out_root, w_world, w_feet, w_legs,
                w_targets, w_sink, w_eased, *_terrain_arrays(ground))
    assert UP_AXIS == 1  # the kernels index Y directly
    if out is None:
        return out_root.astype(np.float32), out_rot
    out[0][...] = out_root
    return out
