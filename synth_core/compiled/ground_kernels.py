"""The ground's height under points, compiled: :meth:`synth_core.runtime.terrain.HeightField.sample`'s
bilinear arithmetic (the same numbers), for the render kernels and for the terrain module itself.

Apart from :mod:`synth_core.compiled.kernels` because the terrain module samples with it while the
kernels' foot lock reads the terrain module's constants: here nothing imports back.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth_core.compiled.jit import prange
from synth_core.compiled.jit import render_jit as jit


@jit()
def ground_at(heights: Any, x0: float, z0: float, spacing: float, x: float, z: float) -> float:
    """terrain.sample at one point (the same arithmetic, in the same order)."""
    nz, nx = heights.shape
    fx = min(max((x - x0) / spacing, 0.0), nx - 1.0)
    fz = min(max((z - z0) / spacing, 0.0), nz - 1.0)
    j = min(int(fx), nx - 2)
    i = min(int(fz), nz - 2)
    u, v = fx - j, fz - i
    near = heights[i, j] * (1.0 - u) + heights[i, j + 1] * u
    far = heights[i + 1, j] * (1.0 - u) + heights[i + 1, j + 1] * u
    return float(near * (1.0 - v) + far * v)


@jit(parallel=True)
def _ground_many(heights: Any, x0: float, z0: float, spacing: float, x: Any, z: Any, out: Any) -> None:
    for i in prange(x.shape[0]):
        out[i] = ground_at(heights, x0, z0, spacing, x[i], z[i])


def ground_samples(heights: NDArray[np.float64], x0: float, z0: float, spacing: float,
                   x: NDArray[np.float64], z: NDArray[np.float64]) -> NDArray[np.float64]:
    """terrain.sample, compiled (the same numbers): the body's footprint samples 20 points a
    character-frame, which numpy's gathers made 10 us of it (more than the whole flat render)."""
    x, z = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(z, np.float64))
    out = np.empty(x.size)
    _ground_many(heights, float(x0), float(z0), float(spacing), np.ascontiguousarray(x).ravel(),
                 np.ascontiguousarray(z).ravel(), out)
    return out.reshape(x.shape)
