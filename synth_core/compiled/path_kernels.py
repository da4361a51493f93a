"""A path's timing smoothed and its shape kept (:func:`synth_core.runtime.gaussian.along_frames`):
each frame's point walked along the path's own segments by the Gaussian average of the distance
along it around that frame; and a live session's points checked (:func:`points_fine`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.compiled.jit import jit, prange


@jit(inline="always")
def _step(x: Any, a: int, b: int) -> Any:
    """The straight distance from point a to point b of one path ``x (T, 3)``."""
    return math.sqrt((x[b, 0] - x[a, 0]) ** 2 + (x[b, 1] - x[a, 1]) ** 2 + (x[b, 2] - x[a, 2]) ** 2)


@jit(inline="always")
def _shifts(steps: Any, w: Any, first: int, d: Any, ahead: Any, behind: Any) -> None:
    """``d[i]``: the Gaussian (weights ``w``, centre first) average of the distance along the path
    from frame ``first + i``'s point (``steps (T - 1,)``: from each point to the next): the steps
    either side summed outwards, in a fixed order (frames beyond an end repeat it: steps of 0).
    Every frame's sums in the same order, one weight at a time for all frames (``ahead``,
    ``behind``: scratch like ``d``): the frames' sums are independent, so they run side by side
    (one frame's alone wait on each add before the next: most of the batch's path smoothing)."""
    T, n = steps.shape[0] + 1, d.shape[0]
    d[:], ahead[:], behind[:] = 0.0, 0.0, 0.0
    for j in range(1, len(w)):
        # Frames [lo, hi) have a step j either side (all but those within j of an end).
        lo, hi = min(max(j - first, 0), n), min(max(T - j - first, 0), n)
        lo = min(lo, hi)
        for i in range(lo):
            _shift_on(steps, w[j], first, j, i, d, ahead, behind)
        wj, m = w[j], hi - lo  # (slices: indices known >= 0, no wraparound test to stop SIMD)
        a_to, b_to, d_to = ahead[lo:hi], behind[lo:hi], d[lo:hi]
        a_from, b_from = steps[first + lo + j - 1:first + hi + j - 1], steps[first + lo - j:first + hi - j]
        for i in range(m):
            a_to[i] += a_from[i]
            b_to[i] += b_from[i]
            d_to[i] += wj * (a_to[i] - b_to[i])
        for i in range(max(hi, lo), n):
            _shift_on(steps, w[j], first, j, i, d, ahead, behind)


@jit(inline="always")
def _shift_on(steps: Any, wj: float, first: int, j: int, i: int, d: Any, ahead: Any, behind: Any) -> None:
    """Weight j's term of frame ``first + i``'s average (:func:`_shifts`), near an end: a step
    beyond it is 0."""
    t = first + i
    if t + j < steps.shape[0] + 1:
        ahead[i] += steps[t + j - 1]
    if t - j >= 0:
        behind[i] += steps[t - j]
    d[i] += wj * (ahead[i] - behind[i])


@jit(parallel=True)  # characters side by side: each writes its own rows
def along(x: Any, w: Any, first: int, out: Any) -> None:
    """``out (C, n, 3)``: frames ``[first, first + n)`` of the paths ``x (C, T, 3)``, each frame's
    point moved along its path by :func:`_shifts` (forward where the path ahead is longer). Each
    step's length is one number whatever the window (a live one gives the batch's bits)."""
    T = x.shape[1]
    for c in prange(x.shape[0]):
        xc = x[c]
        lo, hi = max(first - len(w) + 1, 0), min(first + out.shape[1] + len(w) - 1, T)
        steps = np.zeros(max(T - 1, 0))  # only [lo, hi - 1) is read
        for k in range(lo, hi - 1):
            steps[k] = _step(xc, k, k + 1)
        shifts, ahead, behind = np.empty(out.shape[1]), np.empty(out.shape[1]), np.empty(out.shape[1])
        _shifts(steps, w, first, shifts, ahead, behind)
        for i in range(out.shape[1]):
            t = first + i
            d = shifts[i]
            way = 1 if d >= 0.0 else -1
            k, left = t, abs(d)
            while 0 <= k + way < T:
                seg = steps[min(k, k + way)]
                if left <= seg:
                    break
                left -= seg
                k += way
            seg = steps[min(k, k + way)] if 0 <= k + way < T else 0.0
            for a in range(3):
                out[c, i, a] = xc[k, a]
                if seg > 0.0:
                    out[c, i, a] += (xc[k + way, a] - xc[k, a]) * (left / seg)


@jit()
def points_fine(last: Any, pts: Any, limit: float) -> bool:
    """Whether every point of ``pts (C, n, 3)`` is finite and within ``limit`` of the one before
    (``last (C, 3)``: each character's point before them; NaN: none)."""
    ok = True
    for c in range(pts.shape[0]):
        px, py, pz = last[c, 0], last[c, 1], last[c, 2]
        for i in range(pts.shape[1]):
            x, y, z = pts[c, i, 0], pts[c, i, 1], pts[c, i, 2]
            dx, dy, dz = x - px, y - py, z - pz
            ok = ok and math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
            # A NaN last point means none before (a session's first points): no jump to check,
            # and any comparison with NaN is false, so isnan is asked first.
            ok = ok and (math.isnan(px) or dx * dx + dy * dy + dz * dz <= limit * limit)
            px, py, pz = x, y, z
    return ok
