"""Compiled foot targets of the render: plant targets, the root's sink, targets on a terrain.

Passes 2 and 3 of ``synth_core.compiled.kernels._character`` for one character:
:func:`plant_targets` (``footlock.plant_targets``), :func:`ease_sink` (``footlock.ease_sink``) and
:func:`ground_targets` (``terrain.ground_targets``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.compiled.ground_kernels import ground_at
from synth_core.compiled.jit import render_jit
from synth_core.runtime.footlock import EASE_FRAMES
from synth_core.runtime.terrain import BUMP_LEAST

_jit = render_jit


@_jit()
def plant_targets(feet: Any, contacts: Any, out: Any, most: int) -> None:
    """footlock.plant_targets for one character: feet (T, 4, 3), contacts (T, 4); a plant's
    position averaged over its first ``most`` frames at most (and, ``most`` < T, a swing before
    no plant eased out as there)."""
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
            while t < T and contacts[t, f]:
                t += 1
            n = min(t - s, most)
            acc0 = acc1 = acc2 = 0.0
            for u in range(s, s + n):
                acc0 += feet[u, f, 0]
                acc1 += feet[u, f, 1]
                acc2 += feet[u, f, 2]
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
                # A swing whose next plant is not planned yet (a live window; with `most`, one in
                # the low-latency mode) eases its lift-off correction out over half its plant's
                # length, a guess at the swing's: when the next plant comes, little is left to snap.
                if has_before and (has_after or most < T):
                    span = max(t - last_end if has_after else (last_end - last_start + 1) // 2, 1)
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
def ease_sink(sink: Any, limit: float, out: Any) -> None:
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


# What the sink of a frame reads of its pose, per foot (see ``kernels._character``): the ankle-to-toe
# vector, the upper joint's position and the leg's reach. A live window keeps them for its last
# PAD frames, whose sink the next window's first frames read: those are then not posed again.
LEG_TOE, LEG_UP, LEG_REACH = 0, 3, 6
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
def ground_targets(targets: Any, contacts: Any, heights: Any, x0: float, z0: float, spacing: float,
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


