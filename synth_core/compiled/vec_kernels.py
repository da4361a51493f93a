"""Small vector and quaternion helpers (xyzw) for the compiled render kernels.

On tuples of float64 (no allocation per call), inlined by numba into the kernels of
:mod:`synth_core.compiled.kernels`, :mod:`~synth_core.compiled.limb_kernels` and
:mod:`~synth_core.compiled.foot_kernels`; :func:`nlerp_into` blends float32 pose tables.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.compiled.jit import render_jit

_jit = render_jit


@_jit()
def qmul(a: Any, b: Any) -> Any:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


@_jit()
def conj(q: Any) -> Any:
    return (-q[0], -q[1], -q[2], q[3])


@_jit()
def qrot(q: Any, v: Any) -> Any:
    """q v q*, as quat.rotate: v + w t + u x t with t = 2 u x v."""
    ux, uy, uz, w = q
    tx = 2.0 * (uy * v[2] - uz * v[1])
    ty = 2.0 * (uz * v[0] - ux * v[2])
    tz = 2.0 * (ux * v[1] - uy * v[0])
    return (v[0] + w * tx + (uy * tz - uz * ty), v[1] + w * ty + (uz * tx - ux * tz),
            v[2] + w * tz + (ux * ty - uy * tx))


@_jit()
def vadd(a: Any, b: Any) -> Any:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@_jit()
def vsub(a: Any, b: Any) -> Any:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_jit()
def vscale(a: Any, k: float) -> Any:
    return (a[0] * k, a[1] * k, a[2] * k)


@_jit()
def cross(a: Any, b: Any) -> Any:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@_jit()
def dot3(a: Any, b: Any) -> float:
    return float(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


@_jit()
def norm3(a: Any) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@_jit()
def smoothstep(x: float) -> float:
    """3x^2 - 2x^3 of ``x`` clamped to [0, 1]: an ease in and out."""
    x = min(max(x, 0.0), 1.0)
    return float(x * x * (3 - 2 * x))


@_jit()
def v3(a: Any) -> Any:
    return (float(a[0]), float(a[1]), float(a[2]))


@_jit()
def q4(a: Any) -> Any:
    return (float(a[0]), float(a[1]), float(a[2]), float(a[3]))


@_jit()
def put(out: Any, q: Any) -> None:
    for k in range(len(q)):
        out[k] = q[k]


@_jit()
def nlerp_into(a: Any, b: Any, w: Any, out: Any) -> None:
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


