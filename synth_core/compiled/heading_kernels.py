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


# The way a path goes is read across this much of it (metres each side, at most CHORD_FRAMES
# frames each side): one frame's step of a 10 Hz simulator's held, 2 cm-noisy points swung a
# walking horse's body 10 degrees to and fro (edge suite jitter_10hz: yaw 130 deg/s p95 on a
# 15 m curve). A chord centred on a point of a circle is parallel to its tangent there.
CHORD = 0.25
CHORD_FRAMES = 15


@jit(inline="always")
def _way(g: Any, j: int, dx: float, dz: float, chord_frames: int) -> Any:
    """The path's direction at its point j (:func:`_direction`'s ``dx, dz``, its length kept)
    read across about CHORD of it each side at its pace there, within ``chord_frames`` (at most
    CHORD_FRAMES; 1: one step) and the path."""
    d = math.sqrt(dx * dx + dz * dz)
    k = min(j, g.shape[0] - 1 - j, chord_frames, int(math.ceil(CHORD / max(d, 1e-9))))
    if k <= 1:
        return dx, dz
    cx, cz = g[j + k, 0] - g[j - k, 0], g[j + k, 1] - g[j - k, 1]
    c = math.sqrt(cx * cx + cz * cz)
    if c <= 0.0:
        return dx, dz
    return cx * d / c, cz * d / c


@jit(inline="always")
def _leash(ax: float, az: float, px: float, pz: float, pull: float, length: float) -> Any:
    """The anchor ``(ax, az)`` moved ``pull`` toward the point ``(px, pz)`` (no further), then
    dragged to within ``length`` of it; and whether it was dragged (the point moving away faster
    than the pull: a move, not a jitter round where it stands)."""
    dx, dz = px - ax, pz - az
    d = math.sqrt(dx * dx + dz * dz)
    if d <= pull:
        return px, pz, False
    ax, az, d = ax + dx / d * pull, az + dz / d * pull, d - pull
    if d < length:
        return ax, az, False
    return px - dx / (d + pull) * length, pz - dz / (d + pull) * length, True


@jit(inline="always")
def _moving(g: Any, j: int, fps: float, min_speed: float, free_speed: float, length: float, pull: float,
            still_frames: float, chord_frames: int, a: Any) -> Any:
    """Whether the path moves at its point j, and its direction there: at ``free_speed`` or
    faster; at ``min_speed`` or faster where it drags the anchor ``length`` behind it
    (:func:`_leash`) or has left a stop (still for ``still_frames``) and not dragged it yet. Faced away
    from the anchor instead, a slow pivot's body lagged its path (mann_dog turn_on_spot, r 0.2 m:
    a lone stance 1.23 times its gait's longest). ``a``: the anchor's x, z and the frames still,
    moved on to point j."""
    dx, dz = _direction(g, j)
    speed = math.sqrt(dx * dx + dz * dz) * fps
    still = speed < min_speed
    a[0], a[1], taut = _leash(a[0], a[1], g[j, 0], g[j, 1], np.inf if still else pull, length)
    if still:
        a[2] += 1.0
    elif taut or a[2] < still_frames:
        a[2] = 0.0
    if speed >= free_speed or (not still and a[2] >= still_frames) or (taut and not still):
        return True, *_way(g, j, dx, dz, chord_frames)
    return False, dx, dz  # (its direction not read)


@jit(parallel=True)  # characters side by side: each writes its own rows
def headings(g: Any, off: int, ends: bool, fps: float, min_speed: float, free_speed: float, length: float,
             pull: float, still_frames: float, start_speed: float, chord_frames: int, last_dir: Any,
             moved: Any, anchor: Any, held: Any) -> None:
    """Each character's heading direction ``held (C, n, 2)`` over frames ``[t0, t0 + n)``, its path's
    ground points ``g (C, m, 2)`` holding frame t0 at ``off`` and (for a character standing until
    then) as far ahead as known (``ends``: to the path's end): the path's way where it moves
    (:func:`_moving`), held elsewhere; before the first move, the first move's; NaN where none is
    known yet. A simulator's jitter round a standing point, or across a slow start, turned the
    body 270 deg/s back and forth (edge suite, jitter_10hz): slower than ``free_speed``, only a
    path dragging an anchor behind it, or starting from a stop, moves; a path moving at
    ``start_speed`` or faster at its first point starts as from a stop (the low-latency mode knows
    too few points ahead to find its first move: a dog walking off at once faced +Z, then turned
    135 deg, a paw alone). ``last_dir (C, 2)``, ``moved (C,)``, ``anchor (C, 3)`` (x NaN: at the
    first point) carried on."""
    n = held.shape[1]
    for c in prange(g.shape[0]):
        hx, hz = last_dir[c, 0], last_dir[c, 1]
        a = anchor[c]
        if math.isnan(a[0]):
            dx, dz = _direction(g[c], off)
            a[0], a[1] = g[c, off, 0], g[c, off, 1]
            a[2] = still_frames if math.sqrt(dx * dx + dz * dz) * fps >= start_speed else 0.0
        first = -1
        for i in range(n):
            move, dx, dz = _moving(g[c], off + i, fps, min_speed, free_speed, length, pull, still_frames,
                                   chord_frames, a)
            if move:
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
            ahead = a.copy()
            for j in range(off + n, g.shape[1] if ends else g.shape[1] - 1):
                move, dx, dz = _moving(g[c], j, fps, min_speed, free_speed, length, pull, still_frames,
                                       chord_frames, ahead)
                if move:
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
         lean_rate: float, gentle: float, way_step: float, last: Any, last_lean: Any, lean: Any,
         way: Any, turned: Any) -> None:
    """In place, each character's yaw ``(C, n)`` of frames ``[t0, t0 + n)`` turned toward the one
    given by at most ``min(max_rate, max_lateral / v)`` radians a second, v its path's ground speed
    there (``g (C, m, 2)`` holding frame t0 at ``off``, as for :func:`headings`): a body pivots
    only so fast, and at speed turns no faster than its grip allows (v omega: the lateral
    acceleration). ``lean (C, n)``: the body's roll into the turn, radians about its forward axis
    (+Z turned by the yaw; positive: its top toward its right), atan(v omega / g) toward the
    turn's centre (the centripetal acceleration over gravity) less ``gentle`` (a gentle curve
    leans none), within ``max_lean``, reached at most ``lean_rate`` radians a second. ``last``,
    ``last_lean`` ``(C,)``: each one's yaw (NaN: none) and lean the frame before, carried on.
    ``way (C, n, 2)``: the ground direction (x, z) along which a clip's surge (its root's lead on
    steady progress) goes: the path's own one-step central difference (``g``: the path the root
    follows), a unit vector wherever the path steps ``way_step`` (m a frame) or more -- in a tight
    turn at speed the heading trails the path's by up to ~80 deg, and a surge along it put the
    root off the path (the real dog's 0.5 m U-turn at a gallop: 2.5 cm). A shorter step (a still
    or creeping path: nothing or noise) is topped up along the heading by what it lacks, and the
    sum divided by ``way_step`` at least: the heading's unit vector on a still path, the path's
    once it moves, and, where the path backs up under a held heading, shrinking through 0 as the
    step turns round rather than flipping in a frame (the surge's 2 x 4 cm). ``turned (C, n)``: the
    turn into each frame from the one before (radians, left positive; 0 at a first frame)."""
    for c in prange(yaw.shape[0]):
        prev, tilt = last[c], last_lean[c]
        for i in range(yaw.shape[1]):
            want = yaw[c, i]
            d = 0.0
            v = 0.0
            dx, dz = _direction(g[c], off + i)
            run = math.sqrt(dx * dx + dz * dz)  # the path's step
            if not math.isnan(prev):
                v = run * fps
                cap = (max_rate if v * max_rate <= max_lateral else max_lateral / v) / fps
                d = _wrapped(want - prev + math.pi) - math.pi
                d = min(max(d, -cap), cap)
                want = _wrapped(prev + d + math.pi) - math.pi
            omega = d * fps
            turned[c, i] = d
            # Yaw grows turning from +Z toward +X, the left of a body facing +Z (Y up, right-handed),
            # where the turn's centre then is; a roll of +a about +Z tips the top toward -X.
            target = -math.atan(v * omega / 9.81)
            target = min(max(target - gentle, 0.0), max_lean) + max(min(target + gentle, 0.0), -max_lean)
            step = lean_rate / fps
            tilt = tilt + min(max(target - tilt, -step), step)
            yaw[c, i] = want
            lean[c, i] = tilt
            prev = want
            lack = way_step - run
            if lack > 0.0:
                dx, dz = dx + lack * math.sin(want), dz + lack * math.cos(want)
                run = max(math.sqrt(dx * dx + dz * dz), way_step)
            way[c, i, 0], way[c, i, 1] = dx / run, dz / run
        last[c], last_lean[c] = prev, tilt
