"""Gaussian smoothing of paths along their frames, compiled: ``scipy.ndimage.gaussian_filter1d``
bit for bit, for the frames wanted only.

scipy filters every frame of its input, a line (a character's coordinate) at a time; a live
tick's smoothing reads twice the frames it makes, and a batch's lines are short. Here only the
frames wanted are made, each character's frames and coordinates as one run in SIMD lanes, with
scipy's operations in scipy's order (its symmetric kernel's: the centre, then each pair of
neighbours from the farthest in; no fastmath), so a live path stays the batch's path exactly.
A 500-horse batch's smoothing (1,000 frames): 17-64 -> 5 ms; a 2,000-horse live tick's:
3.3-5 -> 0.4-0.8 ms.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from synth_core.compiled import path_kernels
from synth_core.compiled.jit import AVAILABLE

if AVAILABLE:
    import numba


# Narrower than this (frames) the kernel is the identity: its weight one frame away,
# exp(-0.5 / sigma^2), is below 1e-86. Below ~1e-154 scipy's sigma^2 underflows to 0 and it
# divides by it (a fuzzed request's sigma of 1e-308 got a 500).
IDENTITY_SIGMA = 1e-2


@functools.lru_cache(maxsize=16)
def weights(sigma: float) -> NDArray[np.float64]:
    """``gaussian_filter1d``'s kernel for ``sigma`` (its default truncation, 4 sigma), from the
    centre out: its response to an impulse, which is its weights exactly (each output there is
    one weight times one, plus zeros)."""
    r = int(4.0 * sigma + 0.5)
    impulse = np.zeros(4 * r + 1)
    impulse[2 * r] = 1.0
    kernel = np.array(gaussian_filter1d(impulse, sigma)[2 * r:3 * r + 1])
    kernel.setflags(write=False)  # shared by every caller (cached)
    return kernel


def _rows(x: Any, w: Any, first: int, out: Any) -> None:
    C, N = out.shape[0], out.shape[1] * out.shape[2]
    K = x.shape[2]
    for c in numba.prange(C):
        xc = x[c].reshape(-1)  # frames x coordinates, flat: a frame j away is j K away
        oc = out[c].reshape(-1)
        a = first * K
        centre = xc[a:a + N]
        for i in range(N):
            oc[i] = centre[i] * w[0]
        for j in range(len(w) - 1, 0, -1):  # scipy's order: the pairs from the farthest in
            wj = w[j]
            before, after = xc[a - j * K:a - j * K + N], xc[a + j * K:a + j * K + N]
            for i in range(N):  # (slices: indices known >= 0, no wraparound test to stop SIMD)
                oc[i] += (before[i] + after[i]) * wj


if AVAILABLE:
    _rows = numba.njit(cache=True, parallel=True, nogil=True)(_rows)


def smooth_frames(x: NDArray[np.float64], sigma: float, first: int, n: int) -> NDArray[np.float64]:
    """Frames ``[first, first + n)`` of ``gaussian_filter1d(x, sigma, axis=1, mode="nearest")``
    for ``x (C, T, K)`` float64: compiled where those frames' windows (4 sigma either side) lie
    within ``x`` (the ``mode`` then reads nothing), else scipy's."""
    if sigma < IDENTITY_SIGMA:
        return np.array(x[:, first:first + n], np.float64)
    kernel = weights(float(sigma))
    r = len(kernel) - 1
    if not AVAILABLE or first < r or first + n + r > x.shape[1]:
        return np.asarray(gaussian_filter1d(x, sigma, axis=1, mode="nearest")[:, first:first + n])
    out = np.empty((x.shape[0], n, x.shape[2]))
    _rows(np.ascontiguousarray(x, np.float64), kernel, first, out)
    return out


def along_frames(x: NDArray[np.float64], sigma: float, first: int, n: int,
                 out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Frames ``[first, first + n)`` of the paths ``x (C, T, 3)`` with their *timing* smoothed and
    their shape kept: each frame's point moved along its path's own segments by the Gaussian
    average (``sigma`` frames) of the distance along the path around that frame -- the arc length
    smoothed in time, read back on the path (:mod:`synth_core.compiled.path_kernels`). A
    simulator's held or uneven steps become an even pace while the point stays on the line it
    sent: the simulator is the authority on where an agent is (issue 27). Smoothing the positions
    themselves (:func:`smooth_frames`) cut a 0.5 m corner at a horse's gallop by 18 cm: a
    circle's points averaged over +-sigma frames lie inside it, by r (1 - exp(-(w sigma)^2 / 2)),
    w its turn rate. Each frame reads only the points within the Gaussian's radius of it, in a
    fixed order, so a live window gives the batch's numbers bit for bit. ``out``: written there
    (``(C, n, 3)`` float64, any strides: a live session's path columns) and returned."""
    out = np.empty((x.shape[0], n, x.shape[2])) if out is None else out
    assert out.shape == (x.shape[0], n, x.shape[2]) and out.dtype == np.float64
    if sigma < IDENTITY_SIGMA:
        out[...] = x[:, first:first + n]
        return out
    path_kernels.along(np.ascontiguousarray(x, np.float64), weights(float(sigma)), first, out)
    return out
