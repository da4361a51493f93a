"""Batched quaternion algebra on ``(..., 4)`` arrays, **xyzw** (scalar last, as scipy and glTF).

Every function broadcasts over leading axes and keeps the input's float dtype. Conventions match
``scipy.spatial.transform.Rotation`` (``from_quat``/``as_quat`` are xyzw, ``apply`` rotates
vectors actively), and the tests hold them to it on random inputs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.floating]

_EPS = 1e-12


def _as_float(x: ArrayLike) -> Array:
    a = np.asarray(x)
    return a if np.issubdtype(a.dtype, np.floating) else a.astype(np.float64)


def _check_last(name: str, a: Array, n: int) -> None:
    if a.shape[-1:] != (n,):
        raise ValueError(f"Expected `{name}` to have shape (..., {n}), got {a.shape}")


def identity(shape: tuple[int, ...] = (), dtype: type = np.float32) -> Array:
    """Identity quaternions of the given leading shape."""
    q: Array = np.zeros((*shape, 4), dtype=dtype)
    q[..., 3] = 1.0
    return q


def normalize(q: ArrayLike) -> Array:
    """Unit-norm quaternions; a zero quaternion becomes the identity rather than NaN."""
    q = _as_float(q)
    _check_last("q", q, 4)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    ident = np.zeros_like(q)
    ident[..., 3] = 1.0
    return np.where(norm > _EPS, q / np.maximum(norm, _EPS), ident)


def mul(a: ArrayLike, b: ArrayLike) -> Array:
    """Hamilton product ``a * b``: the rotation ``b`` followed by ``a``."""
    a, b = _as_float(a), _as_float(b)
    _check_last("a", a, 4)
    _check_last("b", b, 4)
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def inv(q: ArrayLike) -> Array:
    """Inverse of unit quaternions (the conjugate)."""
    q = _as_float(q)
    _check_last("q", q, 4)
    return q * np.array([-1.0, -1.0, -1.0, 1.0], dtype=q.dtype)


def rotate(q: ArrayLike, v: ArrayLike) -> Array:
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)`` (broadcasting)."""
    q, v = _as_float(q), _as_float(v)
    _check_last("q", q, 4)
    _check_last("v", v, 3)
    # v' = v + 2w (u x v) + 2 u x (u x v), with u the vector part: no matrix per element.
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def from_axis_angle(axis: ArrayLike, angle: ArrayLike) -> Array:
    """Quaternions rotating by ``angle`` radians about ``axis (..., 3)`` (normalized here)."""
    axis, angle = _as_float(axis), _as_float(angle)
    _check_last("axis", axis, 3)
    norm = np.linalg.norm(axis, axis=-1, keepdims=True)
    unit = axis / np.maximum(norm, _EPS)
    half = 0.5 * np.asarray(angle)[..., None]
    return np.concatenate([unit * np.sin(half), np.cos(half)], axis=-1)


def from_rotvec(rotvec: ArrayLike) -> Array:
    """Quaternions from rotation vectors (axis times angle in radians); small angles are exact."""
    rotvec = _as_float(rotvec)
    _check_last("rotvec", rotvec, 3)
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(a/2)/a -> 1/2 - a^2/48 near zero: branch-free so tiny angles keep full precision.
    small = angle < 1e-4
    scale = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([rotvec * scale, np.cos(half)], axis=-1)


def to_rotvec(q: ArrayLike) -> Array:
    """Rotation vectors (axis times angle, angle in [0, pi]) of quaternions."""
    q = _as_float(q)
    _check_last("q", q, 4)
    q = np.where(q[..., 3:] < 0, -q, q)  # shortest arc
    vec_norm = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(vec_norm, q[..., 3:])
    small = vec_norm < 1e-6
    scale = np.where(small, 2.0 / np.maximum(q[..., 3:], _EPS), angle / np.where(small, 1.0, vec_norm))
    return q[..., :3] * scale


def angle(q: ArrayLike) -> Array:
    """Rotation angle in radians, in [0, pi]."""
    q = _as_float(q)
    _check_last("q", q, 4)
    vec_norm = np.linalg.norm(q[..., :3], axis=-1)
    return np.asarray(2.0 * np.arctan2(vec_norm, np.abs(q[..., 3])))


def to_matrix(q: ArrayLike) -> Array:
    """Rotation matrices ``(..., 3, 3)`` of unit quaternions."""
    q = _as_float(q)
    _check_last("q", q, 4)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def from_matrix(m: ArrayLike) -> Array:
    """Unit quaternions (w >= 0) of rotation matrices ``(..., 3, 3)``.

    Shepperd's method, branch-free: compute all four candidate quaternions and keep, per
    element, the one with the largest (best conditioned) pivot.
    """
    m = _as_float(m)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"Expected `m` to have shape (..., 3, 3), got {m.shape}")
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    candidates = np.stack(
        [
            np.stack([1 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0],
                      m[..., 0, 2] + m[..., 2, 0], m[..., 2, 1] - m[..., 1, 2]], -1),
            np.stack([m[..., 0, 1] + m[..., 1, 0], 1 - m00 + m11 - m22,
                      m[..., 1, 2] + m[..., 2, 1], m[..., 0, 2] - m[..., 2, 0]], -1),
            np.stack([m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1],
                      1 - m00 - m11 + m22, m[..., 1, 0] - m[..., 0, 1]], -1),
            np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                      m[..., 1, 0] - m[..., 0, 1], 1 + trace], -1),
        ],
        axis=-2,
    )
    pivot = np.stack([m00, m11, m22, trace], -1).argmax(-1)
    best = normalize(np.take_along_axis(candidates, pivot[..., None, None], axis=-2)[..., 0, :])
    return np.where(best[..., 3:] < 0, -best, best)


def between(u: ArrayLike, v: ArrayLike) -> Array:
    """The smallest rotation taking direction ``u (..., 3)`` onto direction ``v (..., 3)``.

    Opposite vectors get a half turn about an axis perpendicular to ``u``.
    """
    u, v = _as_float(u), _as_float(v)
    _check_last("u", u, 3)
    _check_last("v", v, 3)
    u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), _EPS)
    v = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS)
    u, v = np.broadcast_arrays(u, v)
    w = 1.0 + np.sum(u * v, axis=-1, keepdims=True)
    axis = np.cross(u, v)
    # For u ~ -v the cross product vanishes: pick any axis perpendicular to u.
    ortho = np.cross(u, np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
    opposite = w < 1e-9
    q = np.concatenate([np.where(opposite, ortho, axis), np.where(opposite, 0.0, w)], axis=-1)
    return normalize(q)


def dot(a: ArrayLike, b: ArrayLike) -> Array:
    """4D dot product of quaternions."""
    return np.asarray(np.sum(_as_float(a) * _as_float(b), axis=-1))


def nlerp(a: ArrayLike, b: ArrayLike, t: ArrayLike) -> Array:
    """Normalized linear interpolation along the shorter arc; ``t`` broadcasts as ``(...)``."""
    a, b = _as_float(a), _as_float(b)
    t = np.asarray(t, dtype=a.dtype)[..., None]
    b = np.where(dot(a, b)[..., None] < 0, -b, b)
    return normalize((1.0 - t) * a + t * b)


def slerp(a: ArrayLike, b: ArrayLike, t: ArrayLike) -> Array:
    """Spherical linear interpolation along the shorter arc; ``t`` broadcasts as ``(...)``."""
    a, b = _as_float(a), _as_float(b)
    t = np.asarray(t, dtype=a.dtype)[..., None]
    d = dot(a, b)[..., None]
    b = np.where(d < 0, -b, b)
    d = np.clip(np.abs(d), -1.0, 1.0)
    theta = np.arccos(d)
    sin_theta = np.sin(theta)
    # Nearly parallel: sin(theta) -> 0, fall back to nlerp weights (same limit, no 0/0).
    near = sin_theta < 1e-6
    safe = np.where(near, 1.0, sin_theta)
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    wb = np.where(near, t, np.sin(t * theta) / safe)
    return normalize(wa * a + wb * b)


def make_continuous(q: ArrayLike, axis: int = 0) -> Array:
    """Hemisphere continuity: flip signs along ``axis`` so neighbours have a non-negative dot.

    ``q`` and ``-q`` are the same rotation; blending or differentiating across a sign flip is
    not. The flip decision accumulates (a cumulative parity), so the whole sequence is fixed in
    one vectorized pass.
    """
    q = np.moveaxis(_as_float(q), axis, 0)
    _check_last("q", q, 4)
    if q.shape[0] < 2:
        return np.moveaxis(q.copy(), 0, axis)
    flips = np.sum(q[1:] * q[:-1], axis=-1) < 0
    parity = np.concatenate([np.zeros_like(flips[:1]), np.cumsum(flips, axis=0) % 2 == 1], axis=0)
    out = np.where(parity[..., None], -q, q)
    return np.moveaxis(out, 0, axis)
