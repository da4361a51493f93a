"""The planner's headings, compiled or interpreted as the rest of it
(:mod:`synth_core.compiled.plan_kernels`): each character's heading from its path's ground
direction (:func:`headings`), then turned toward it no faster than a body pivots or its grip
allows, and leant into the turn (:func:`turn`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.compiled.jit import jit, prange


@jit()
def _direction(g: Any, j: int) -> Any:
    """The path's ground direction at its point j (np.gradient's: central, one-sided at its ends)."""
    m = g.shape[0]
    if m < 2:
        return 0.0, 0.0
    if j == 0:
        return g[1, 0] - g[0, 0], g[1, 1] - g[0, 1]
    if j == m - 1:
        return g[j, 0] - g[j - 1, 0], g[j, 1] - g[j - 1, 1]
    return (g[j + 1, 0] - g[j - 1, 0]) / 2.0, (g[j + 1, 1] - g[j - 1, 1]) / 2.0


@jit(parallel=True)  # characters side by side: each writes its own rows
def headings(g: Any, off: int, ends: bool, fps: float, min_speed: float, last_dir: Any, moved: Any,
             held: Any) -> None:
    """Each character's heading direction ``held (C, n, 2)`` over frames ``[t0, t0 + n)``, its path's
    ground points ``g (C, m, 2)`` holding frame t0 at ``off`` and (for a character standing until
    then) as far ahead as known (``ends``: to the path's end): the path's direction, held where it
    moves slower than ``min_speed``; before the first move, the first move's; NaN where none is
    known yet. ``last_dir (C, 2)`` and ``moved (C,)`` carried on."""
    n = held.shape[1]
    for c in prange(g.shape[0]):
        hx, hz = last_dir[c, 0], last_dir[c, 1]
        first = -1
        for i in range(n):
            dx, dz = _direction(g[c], off + i)
            if math.sqrt(dx * dx + dz * dz) * fps >= min_speed:
                hx, hz = dx, dz
                if first < 0:
                    first = i
            held[c, i, 0], held[c, i, 1] = hx, hz
        if first >= 0:
            last_dir[c, 0], last_dir[c, 1] = hx, hz
        if moved[c]:
            continue
        fx, fz = np.nan, np.nan  # before its first move it faces the way it first moves
        if first >= 0:
            fx, fz = held[c, first, 0], held[c, first, 1]
        else:
            for j in range(off + n, g.shape[1] if ends else g.shape[1] - 1):
                dx, dz = _direction(g[c], j)
                if math.sqrt(dx * dx + dz * dz) * fps >= min_speed:
                    fx, fz = dx, dz
                    break
        for i in range(n if first < 0 else first):
            held[c, i, 0], held[c, i, 1] = fx, fz
        moved[c] = first >= 0


@jit(inline="always")
def _wrapped(w: float) -> float:
    """``w % (2 pi)`` (Python's, as numba computes it: fmod, then a negative one moved up), with
    the division skipped where ``w`` is within [0, 2 pi) already -- the modulo of such a ``w`` is
    ``w`` exactly (-0.0 aside: +0.0, the same once pi is taken off) -- as a heading turning
    less than half a turn a frame is (two a frame per character)."""
    return w if 0.0 <= w < 2.0 * math.pi else w % (2.0 * math.pi)


@jit(parallel=True)  # characters side by side: each writes its own rows
def turn(yaw: Any, g: Any, off: int, fps: float, max_rate: float, max_lateral: float, max_lean: float,
         lean_rate: float, gentle: float, last: Any, last_lean: Any, lean: Any) -> None:
    """In place, each character's yaw ``(C, n)`` of frames ``[t0, t0 + n)`` turned toward the one
    given by at most ``min(max_rate, max_lateral / v)`` radians a second, v its path's ground speed
    there (``g (C, m, 2)`` holding frame t0 at ``off``, as for :func:`headings`): a body pivots
    only so fast, and at speed turns no faster than its grip allows (v omega: the lateral
    acceleration). ``lean (C, n)``: the body's roll into the turn, radians about its forward axis
    (+Z turned by the yaw; positive: its top toward its right), atan(v omega / g) toward the
    turn's centre (the centripetal acceleration over gravity) less ``gentle`` (a gentle curve
    leans none), within ``max_lean``, reached at most ``lean_rate`` radians a second. ``last``,
    ``last_lean`` ``(C,)``: each one's yaw (NaN: none) and lean the frame before, carried on."""
    for c in prange(yaw.shape[0]):
        prev, tilt = last[c], last_lean[c]
        for i in range(yaw.shape[1]):
            want = yaw[c, i]
            omega = 0.0
            v = 0.0
            if not math.isnan(prev):
                dx, dz = _direction(g[c], off + i)
                v = math.sqrt(dx * dx + dz * dz) * fps
                cap = (max_rate if v * max_rate <= max_lateral else max_lateral / v) / fps
                d = _wrapped(want - prev + math.pi) - math.pi
                d = min(max(d, -cap), cap)
                want = _wrapped(prev + d + math.pi) - math.pi
                omega = d * fps
            # Yaw grows turning from +Z toward +X, the left of a body facing +Z (Y up, right-handed),
            # where the turn's centre then is; a roll of +a about +Z tips the top toward -X.
            target = -math.atan(v * omega / 9.81)
            target = min(max(target - gentle, 0.0), max_lean) + max(min(target + gentle, 0.0), -max_lean)
            step = lean_rate / fps
            tilt = tilt + min(max(target - tilt, -step), step)
            yaw[c, i] = want
            lean[c, i] = tilt
            prev = want
        last[c], last_lean[c] = prev, tilt
