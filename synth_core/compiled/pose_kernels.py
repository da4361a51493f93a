"""Pass 1 of the render without its FK: a character's frames blended from the plan's table rows
(and the piece fading out), turned to the heading, leant into the turn and put on the path --
or its root alone, for a character nobody is sent the pose of."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.compiled.jit import render_jit
from synth_core.compiled.vec_kernels import nlerp_into, put, q4, qmul

_jit = render_jit


@_jit()
def assemble(poses: Any, height: Any, surge: Any, rows: Any, weights: Any, yaw: Any, lean: Any, path: Any,
             way: Any, h: float, out_rot: Any, out_root: Any) -> None:
    """Pass 1 without FK: blended, turned, warped pose of each frame of one character (its surge
    along the path's ``way (T, 2)``, heading_kernels.turn).
    ``poses (K, 4, J)``: the pose table components first (see :func:`nlerp_into`); the frame is
    blended that way and written out as xyzw rows (``out_rot (T, J, 4)``)."""
    T, J = out_rot.shape[0], out_rot.shape[1]
    before = np.empty((4, J), np.float32)
    now = np.empty((4, J), np.float32)
    pose = np.empty((4, J), np.float32)
    for t in range(T):
        r0, r1, p0, p1 = rows[t, 0], rows[t, 1], rows[t, 2], rows[t, 3]
        w, pw, keep = weights[t, 0], weights[t, 1], weights[t, 2]
        ht, sg = _height_surge(height, surge, rows[t], weights[t])
        if keep > 0:
            nlerp_into(poses[r0], poses[r1], w, now)
            nlerp_into(poses[p0], poses[p1], pw, before)
            nlerp_into(now, before, keep, pose)
        else:
            nlerp_into(poses[r0], poses[r1], w, pose)
        frame = out_rot[t]
        for j in range(J):
            for k in range(4):
                frame[j, k] = pose[k, j]
        _put_root(ht, sg, path[t], way[t], h, out_root[t])
        sh, ch = math.sin(0.5 * yaw[t]), math.cos(0.5 * yaw[t])
        if lean[t] != 0.0:  # turned, then rolled about its forward axis: (yaw about Y) (lean about Z)
            sr, cr = math.sin(0.5 * lean[t]), math.cos(0.5 * lean[t])
            put(frame[0], qmul((sh * sr, sh * cr, ch * sr, ch * cr), q4(frame[0])))
        else:
            put(frame[0], qmul((0.0, sh, 0.0, ch), q4(frame[0])))


@_jit(inline="always")
def _blend(a0: float, a1: float, b0: float, b1: float, w: float, pw: float, keep: float) -> float:
    """A value of a frame's table rows blended as its pose is: its rows' ``a0``, ``a1`` by ``w``,
    over the piece fading out's ``b0``, ``b1`` (by ``pw``) by ``keep``."""
    v = a0 * (1 - w) + a1 * w
    if keep > 0:
        v = v * (1 - keep) + (b0 * (1 - pw) + b1 * pw) * keep
    return v


@_jit(inline="always")
def _height_surge(height: Any, surge: Any, row: Any, weight: Any) -> tuple[float, float]:
    """A frame's root height and surge blended from its table rows ``row`` (r0, r1, and the piece
    fading out: p0, p1) by ``weight`` (w, pw, keep), as its pose is."""
    r0, r1, p0, p1 = row[0], row[1], row[2], row[3]
    w, pw, keep = weight[0], weight[1], weight[2]
    return (_blend(height[r0], height[r1], height[p0], height[p1], w, pw, keep),
            _blend(surge[r0], surge[r1], surge[p0], surge[p1], w, pw, keep))


@_jit()
def _put_root(ht: float, sg: float, path: Any, way: Any, h: float, out: Any) -> None:
    """A frame's root on the path, its height and its surge along the path's way (both blended
    already)."""
    out[0] = path[0] + way[0] * sg * h
    out[1] = path[1] + ht * h
    out[2] = path[2] + way[1] * sg * h


@_jit()
def clip_soles(paws: Any, rows: Any, weights: Any, path: Any, terrain: bool, h: float) -> Any:
    """Each foot's standing height ``(T, 4)`` as the frame's clips have it: its rows' (``paws (K,
    4)``, bank.standing_heights) blended linearly by the weights the pose is blended by, in the
    feet's unit space (:func:`~synth_core.compiled.foot_kernels.measure_feet`: over the path's
    height, on a terrain over the body's ground). A plant stands there, not at its frames' FK:
    a pose blended from two frames apart in a stance (a piece fading out, held on its last frame,
    while the next plays on) swings the planted leg through the chord between them, and FK put the
    foot up to 4 cm under either frame's (the real dog accelerating through its walk), while a
    row lifting the foot raised it."""
    out = np.empty((rows.shape[0], 4))
    for t in range(rows.shape[0]):
        r0, r1, p0, p1 = rows[t, 0], rows[t, 1], rows[t, 2], rows[t, 3]
        w, pw, keep = weights[t, 0], weights[t, 1], weights[t, 2]
        base = 0.0 if terrain else path[t, 1] / h
        for f in range(4):
            out[t, f] = base + _blend(paws[r0, f], paws[r1, f], paws[p0, f], paws[p1, f], w, pw, keep)
    return out


@_jit()
def root_only(height: Any, surge: Any, rows: Any, weights: Any, path: Any, way: Any, h: float,
              out_root: Any) -> None:
    """Pass 1's root alone (:func:`assemble` without the pose): a character at root_gait detail,
    whose rotations nobody is sent -- the plan's root, before the foot lock's sink."""
    for t in range(out_root.shape[0]):
        ht, sg = _height_surge(height, surge, rows[t], weights[t])
        _put_root(ht, sg, path[t], way[t], h, out_root[t])


@_jit()
def lean_tilt(yaw: float, lean: float) -> Any:
    """The world rotation of a lean: ``lean`` about the forward axis of heading ``yaw``."""
    sr, cr = math.sin(0.5 * lean), math.cos(0.5 * lean)
    return (math.sin(yaw) * sr, 0.0, math.cos(yaw) * sr, cr)
