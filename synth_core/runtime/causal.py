"""Causal smoothing for the low-latency live mode: a path's position and velocity at a frame from
the points up to a few frames after it only.

The batch smooths a path with a Gaussian reading 4 sigma either side (16 frames at the horse's
60 fps), and its speeds read segment centres up to 1.5 segments ahead: exact, and seconds late. A
one-sided average lags -- a gallop at 15 m/s smoothed over a 4-frame lag runs a metre behind its
points -- so here each frame is a **local linear fit**: a line fitted to the points from
``behind`` frames before it to ``ahead`` after it, each weighted by a Gaussian of its distance,
read at the frame (its value: the position; its slope: the velocity). A path moving at a
constant velocity comes out without lag or bias; its noise is averaged over the window; where
``ahead == behind`` the fit's position is the plain (normalized) Gaussian average.

Both are fixed FIR filters: a fit's value is linear in the points, so its coefficients are
computed once per (sigma, window) and applied as one dot product per frame, vectorized over
characters and frames.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

Floats = NDArray[np.float64]


@functools.lru_cache(maxsize=32)
def fit_weights(sigma: float, behind: int, ahead: int) -> tuple[Floats, Floats]:
    """The coefficients of a Gaussian-weighted (``sigma`` frames) line fitted over offsets
    ``[-behind, ahead]`` and read at offset 0: ``(value, slope)``, each ``(behind + ahead + 1,)``
    in offset order. ``sigma`` 0: the value is the frame's own point."""
    offsets = np.arange(-behind, ahead + 1, dtype=np.float64)
    g = np.exp(-0.5 * (offsets / max(sigma, 1e-6)) ** 2)
    X = np.stack([np.ones_like(offsets), offsets], axis=1)
    # (X^T W X)^-1 X^T W: rows are the fit's intercept (the value at 0) and slope.
    XtW = X.T * g
    coef = np.linalg.solve(XtW @ X, XtW)
    value, slope = np.array(coef[0]), np.array(coef[1])
    if sigma <= 0:
        value = (offsets == 0).astype(np.float64)
    value.setflags(write=False)  # shared by every caller (cached)
    slope.setflags(write=False)
    return value, slope


def apply(x: Floats, weights: Floats, behind: int, first: int, n: int) -> Floats:
    """Frames ``[first, first + n)`` of ``x (C, T, K)`` filtered by ``weights`` (offsets from
    ``-behind`` on): ``(C, n, K)``. The frames read must lie within ``x``."""
    a = first - behind
    b = a + n + len(weights) - 1
    if a < 0 or b > x.shape[1]:
        raise ValueError(f"frames [{first}, {first + n}) read [{a}, {b}) of {x.shape[1]}")
    windows = sliding_window_view(x[:, a:b], len(weights), axis=1)  # (C, n, K, taps)
    return np.asarray(windows @ weights)
