"""The ``delta`` rotation encoding: time-axis deltas of quantized rotation vectors, Rice coded.

~2 bytes per joint-frame at <= 0.1 mm world error (docs/wire-format.md has the layout and the
measured figures). One *block* holds one character's ``n`` frames of ``J`` joints:

1. Each local rotation becomes its rotation vector ``r = angle * axis`` (the w >= 0 half of the
   quaternion sphere; |r| <= pi), quantized per joint: ``v = round(r / step_j)``. The rotation
   vector, not the quaternion: three numbers, and a change of ``e`` in it turns the rotation by
   at most ``|e|`` (the exponential map's Jacobian has singular values <= 1), so the step bounds
   the angle: ``|error| <= step * sqrt(3) / 2``.
2. The step comes from the joint's lever arm (:func:`joint_steps`): a joint's rotation error
   moves every joint below it by at most (error x distance), so the shoulder, a metre and a
   half above the hoof, gets a fine step and the pastern a coarse one; each joint on a chain of
   ``d`` rotating joints gets 1/d of the budget ``max_error_m``, so the sum along any chain -- the
   world position error of every joint, the hoof's included -- stays within it.
3. Along time each integer track is stored as its first value, its first change (``v[1] -
   v[0]``), then residuals of the prediction from the last two values (``2 v[t-1] - v[t-2]``):
   motion is smooth, so they are small; zig-zag mapped to unsigned and Rice coded, each track
   with the parameter ``k`` that makes it shortest. A track whose residuals are all zero (an
   end site, a still joint) stores none.

The integers are exact: decoding gives back ``v``, so the only error is step 1's rounding.

Block layout, little-endian; bit ``i`` of a bit section is bit ``i % 8`` of its byte ``i // 8``::

    u8 version (1) | u8 0 | u16 frames n | u16 joints J | u32 block bytes | u32 unary offset
    J x u8 step code: step = 2 ** (-code / 8) radians
    bit section A (from byte 14 + J): per track (joint-major, x y z): k (5 bits; 31: no
        residuals), W0 and W1 (5 bits each); per track its first value and first change,
        zig-zag, in W0 and W1 bits; then, track by track, each residual's low k bits (an
        escaped one: its whole zig-zag value, 32 bits)
    bit section B (from the unary offset): per residual its quotient u >> k in unary
        (that many 0 bits, then a 1); quotient 24 is the escape: the value is in A, 32 bits

A stream of several characters (a WebSocket chunk) is their blocks one after another.
"""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np
from numpy.typing import NDArray

numba: Any
try:
    import numba
except ImportError:  # pragma: no cover - numba is a dependency; the pure-Python encoder still works
    numba = None

VERSION = 1
HEADER = 14  # bytes before the step codes
NO_RESIDUALS = 31
ESCAPE = 24  # a quotient this big: the value is written whole, 32 bits
MAX_ERROR_M = 1.0e-4  # the default world-position error budget: 0.1 mm
MIN_LEVER_M = 0.03  # an end site's rotation still turns a point 3 cm away (the glTF mesh's skin)
MAX_CODE = 216  # step >= 2**-27 rad: |v| < 2**29, its second differences fit 32 bits zig-zagged
_HEAD = struct.Struct("<BBHHII")


class DeltaError(ValueError):
    """A delta stream that cannot be decoded."""


def joint_steps(parents: NDArray[np.integer], offsets: NDArray[np.floating],
                scale: float | NDArray[np.floating] = 1.0,
                max_error_m: float = MAX_ERROR_M) -> NDArray[np.uint8]:
    """Per joint its step code (``step = 2 ** (-code / 8)`` rad): the coarsest step whose rotation
    error, times the joint's lever arm (its farthest descendant, at least ``MIN_LEVER_M``, at
    ``scale``), is within its share of ``max_error_m`` (1/d, d the rotating joints on its
    deepest chain). ``scale`` a float: ``(J,)``; an array of C scales: ``(C, J)``."""
    parents = np.asarray(parents, np.int64)
    bone = np.linalg.norm(np.asarray(offsets, np.float64), axis=-1)
    J = len(parents)
    depth = np.ones(J, np.int64)
    for j in range(1, J):  # parents come first
        depth[j] = depth[parents[j]] + 1
    lever = np.zeros(J)
    chain = depth.copy()  # the depth of the deepest joint below (or at) j
    for j in range(J - 1, 0, -1):  # children before parents
        p = parents[j]
        lever[p] = max(lever[p], lever[j] + bone[j])
        chain[p] = max(chain[p], chain[j])
    lever = np.maximum(lever, MIN_LEVER_M)
    step = max_error_m / (chain * lever) * (2.0 / math.sqrt(3.0))  # at scale 1; lever grows with it
    h = np.asarray(scale, np.float64)
    code = np.ceil(-8.0 * np.log2(step) + 8.0 * np.log2(h)[..., None])
    return np.clip(code, 0, MAX_CODE).astype(np.uint8)


def step_of(code: NDArray[np.uint8]) -> NDArray[np.float64]:
    return np.asarray(2.0 ** (-np.asarray(code, np.float64) / 8.0))


def rotation_vectors(q: NDArray[np.floating]) -> NDArray[np.float64]:
    """Unit xyzw ``(..., 4)`` -> rotation vectors ``(..., 3)`` (angle times axis, angle <= pi)."""
    q = np.asarray(q, np.float64)
    q = np.where(q[..., 3:4] < 0, -q, q)
    s = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:4])
    # angle / s -> 2 / w as s -> 0 (w -> 1): no division by a vanishing norm
    ratio = np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 2.0 / np.maximum(q[..., 3:4], 1e-12))
    return np.asarray(q[..., :3] * ratio)


def quaternions(r: NDArray[np.floating]) -> NDArray[np.float32]:
    """Rotation vectors ``(..., 3)`` -> unit xyzw float32 ``(..., 4)``."""
    r = np.asarray(r, np.float64)
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * angle
    sinc = np.where(angle > 1e-8, np.sin(half) / np.maximum(angle, 1e-300), 0.5 - angle * angle / 48.0)
    return np.concatenate([r * sinc, np.cos(half)], axis=-1).astype(np.float32)


# --- encoder (compiled where numba is installed; the same code runs as plain Python) -----------


def _put(buf: Any, pos: int, value: int, width: int) -> int:  # pragma: no cover - compiled
    """``width`` (<= 32) low bits of ``value`` at bit ``pos`` of ``buf``; the bit after them."""
    if width == 0:
        return pos
    word = (value & ((1 << width) - 1)) << (pos & 7)  # < 2**39: fits int64
    byte = pos >> 3
    for b in range(((pos & 7) + width + 7) >> 3):  # the buffer is zeroed: OR each byte in
        buf[byte + b] |= np.uint8((word >> (8 * b)) & 0xFF)
    return pos + width


def _quantize_all(q: Any, step: Any, v: Any) -> None:  # pragma: no cover - compiled
    """:func:`quantize`'s integers, compiled: ``q (C, n, J, 4)``, ``step (C, J)`` -> ``v (C, n, J * 3)``."""
    C, n, J = q.shape[:3]
    for c in numba.prange(C):
        for t in range(n):
            for j in range(J):
                x, y, z, w = (np.float64(q[c, t, j, 0]), np.float64(q[c, t, j, 1]),
                              np.float64(q[c, t, j, 2]), np.float64(q[c, t, j, 3]))
                if w < 0:
                    x, y, z, w = -x, -y, -z, -w
                s = math.sqrt(x * x + y * y + z * z)
                ratio = 2.0 * math.atan2(s, w) / s if s > 1e-12 else 2.0 / max(w, 1e-12)
                inv = ratio / step[c, j]
                v[c, t, 3 * j] = np.int64(np.rint(x * inv))
                v[c, t, 3 * j + 1] = np.int64(np.rint(y * inv))
                v[c, t, 3 * j + 2] = np.int64(np.rint(z * inv))


def _zigzag(r: int) -> int:  # pragma: no cover - compiled
    return 2 * r if r >= 0 else -2 * r - 1


def _residuals(v: Any, res: Any) -> None:  # pragma: no cover - compiled
    """``v (n, T)`` int64 -> ``res (n - 2, T)``: zig-zag residuals of frames 2.. predicted from
    the two before (``2 v[t-1] - v[t-2]``)."""
    n, T = v.shape
    for t in range(2, n):
        for i in range(T):
            res[t - 2, i] = _zigzag(v[t, i] - 2 * v[t - 1, i] + v[t - 2, i])


def _width(z: int) -> int:  # pragma: no cover - compiled
    w = 0
    while z >> w:
        w += 1
    return w


def _heads(v: Any, i: int) -> tuple[int, int, int, int]:  # pragma: no cover - compiled
    """Track ``i``'s first value and first change, zig-zag, and their widths in bits."""
    n = v.shape[0]
    z0 = _zigzag(v[0, i]) if n > 0 else 0
    z1 = _zigzag(v[1, i] - v[0, i]) if n > 1 else 0
    return z0, _width(z0), z1, _width(z1)


def _cost(res: Any, i: int, k: int) -> int:  # pragma: no cover - compiled
    bits = 0
    for t in range(res.shape[0]):
        q = res[t, i] >> k
        bits += ESCAPE + 1 + 32 if q >= ESCAPE else q + 1 + k
    return bits


def _choose_k(res: Any, i: int) -> int:  # pragma: no cover - compiled
    """The Rice parameter that makes track ``i`` shortest (searched around log2 of its mean)."""
    total = 0
    nonzero = False
    for t in range(res.shape[0]):
        total += res[t, i]
        nonzero |= res[t, i] != 0
    if not nonzero:
        return NO_RESIDUALS
    mean = total / res.shape[0]
    guess = 0
    while guess < 22 and (1 << (guess + 1)) <= mean:
        guess += 1
    best, best_k = -1, 0
    for k in range(max(guess - 2, 0), min(guess + 3, ESCAPE)):
        c = _cost(res, i, k)
        if best < 0 or c < best:
            best, best_k = c, k
    return best_k


def _plan_block(v: Any, ks: Any) -> tuple[int, int]:  # pragma: no cover - compiled
    """Each track's Rice parameter into ``ks``; the block's (unary offset, length in bytes) --
    so that every block's place is known before any is written."""
    n, T = v.shape
    res = np.zeros((max(n - 2, 0), T), np.int64)
    _residuals(v, res)
    bits_a = 8 * (HEADER + T // 3) + 15 * T
    bits_b = 0
    for i in range(T):
        _, w0, _, w1 = _heads(v, i)
        bits_a += w0 + w1
        k = _choose_k(res, i) if n > 2 else NO_RESIDUALS
        ks[i] = k
        if k != NO_RESIDUALS:
            for t in range(n - 2):
                q = res[t, i] >> k
                bits_a += 32 if q >= ESCAPE else k
                bits_b += min(q, ESCAPE) + 1
    unary = (bits_a + 7) >> 3
    return unary, unary + ((bits_b + 7) >> 3)


def _write_block(v: Any, codes: Any, ks: Any, unary: int, size: int,
                 out: Any) -> None:  # pragma: no cover - compiled
    """One block of ``v (n, J * 3)`` int64 into ``out`` (zeroed, ``size`` bytes), as planned."""
    n, T = v.shape
    J = T // 3
    res = np.zeros((max(n - 2, 0), T), np.int64)
    _residuals(v, res)
    for j in range(J):
        out[HEADER + j] = codes[j]
    pos = 8 * (HEADER + J)
    for i in range(T):
        _, w0, _, w1 = _heads(v, i)
        pos = _put(out, pos, ks[i], 5)
        pos = _put(out, pos, w0, 5)
        pos = _put(out, pos, w1, 5)
    for i in range(T):
        z0, w0, z1, w1 = _heads(v, i)
        pos = _put(out, pos, z0, w0)
        pos = _put(out, pos, z1, w1)
    for i in range(T):
        k = ks[i]
        if k == NO_RESIDUALS:
            continue
        for t in range(n - 2):
            u = res[t, i]
            if (u >> k) >= ESCAPE:
                pos = _put(out, pos, u, 32)
            else:
                pos = _put(out, pos, u & ((1 << k) - 1), k)
    pos = 8 * unary
    for i in range(T):
        k = ks[i]
        if k == NO_RESIDUALS:
            continue
        for t in range(n - 2):
            pos += min(res[t, i] >> k, ESCAPE)  # zeros: the buffer is zeroed
            pos = _put(out, pos, 1, 1)
    out[0] = VERSION
    out[2], out[3] = n & 0xFF, n >> 8
    out[4], out[5] = J & 0xFF, J >> 8
    for b in range(4):
        out[6 + b] = (size >> (8 * b)) & 0xFF
        out[10 + b] = (unary >> (8 * b)) & 0xFF


def _plan_all(v: Any, ks: Any, plans: Any) -> None:  # pragma: no cover - compiled
    for c in numba.prange(v.shape[0]):
        plans[c, 0], plans[c, 1] = _plan_block(v[c], ks[c])


def _write_all(v: Any, codes: Any, ks: Any, plans: Any, starts: Any, out: Any) -> None:  # pragma: no cover
    for c in numba.prange(v.shape[0]):
        _write_block(v[c], codes[c], ks[c], plans[c, 0], plans[c, 1],
                     out[starts[c]:starts[c] + plans[c, 1]])


def _plan_all_py(v: Any, ks: Any, plans: Any) -> None:
    for c in range(v.shape[0]):
        plans[c, 0], plans[c, 1] = _plan_block(v[c], ks[c])


def _write_all_py(v: Any, codes: Any, ks: Any, plans: Any, starts: Any, out: Any) -> None:
    for c in range(v.shape[0]):
        _write_block(v[c], codes[c], ks[c], plans[c, 0], plans[c, 1],
                     out[starts[c]:starts[c] + plans[c, 1]])


if numba is not None:
    _put = numba.njit(cache=True, nogil=True, inline="always")(_put)
    _zigzag = numba.njit(cache=True, nogil=True, inline="always")(_zigzag)
    _width = numba.njit(cache=True, nogil=True, inline="always")(_width)
    _heads = numba.njit(cache=True, nogil=True)(_heads)
    _residuals = numba.njit(cache=True, nogil=True)(_residuals)
    _cost = numba.njit(cache=True, nogil=True)(_cost)
    _choose_k = numba.njit(cache=True, nogil=True)(_choose_k)
    _plan_block = numba.njit(cache=True, nogil=True)(_plan_block)
    _write_block = numba.njit(cache=True, nogil=True)(_write_block)
    _quantize_all = numba.njit(parallel=True, cache=True, nogil=True)(_quantize_all)
    _plan_all = numba.njit(parallel=True, cache=True, nogil=True)(_plan_all)
    _write_all = numba.njit(parallel=True, cache=True, nogil=True)(_write_all)
else:  # pragma: no cover
    _plan_all, _write_all = _plan_all_py, _write_all_py


def quantize(q: NDArray[np.floating], codes: NDArray[np.uint8]) -> NDArray[np.int64]:
    """``q (C, n, J, 4)``, ``codes (C, J)`` -> the integers ``(C, n, J * 3)`` a block stores."""
    r = rotation_vectors(q)
    step = step_of(codes)[:, None, :, None]
    v = np.rint(r / step).astype(np.int64)
    return v.reshape(*v.shape[:2], -1)


def encode(q: NDArray[np.floating], codes: NDArray[np.uint8],
           compiled: bool = True) -> tuple[NDArray[np.uint8], NDArray[np.int64]]:
    """Blocks of characters' rotations ``q (C, n, J, 4)`` at step ``codes (C, J)`` (or ``(J,)``
    for all), one after another in one buffer, and where each starts ``(C + 1,)``: character
    ``c`` is ``buf[starts[c]:starts[c + 1]]``. ``compiled=False``: the same encoder run as
    plain Python (the reference the tests hold the compiled one to)."""
    q = np.asarray(q)
    if q.ndim != 4 or q.shape[-1] != 4:
        raise DeltaError(f"expected rotations of shape (C, n, J, 4), got {q.shape}")
    C, n, J = q.shape[:3]
    codes = np.ascontiguousarray(np.broadcast_to(np.asarray(codes, np.uint8), (C, J)))
    if n > 0xFFFF or J > 0xFFFF:
        raise DeltaError(f"a block holds at most 65535 frames and joints, got {n} x {J}")
    if compiled and numba is not None:
        v = np.empty((C, n, 3 * J), np.int64)
        _quantize_all(np.ascontiguousarray(q, np.float32), step_of(codes), v)
    else:
        v = np.ascontiguousarray(quantize(q, codes))
    ks = np.zeros((C, 3 * J), np.int64)
    plans = np.zeros((C, 2), np.int64)  # per block: unary offset, length
    (_plan_all if compiled else _plan_all_py)(v, ks, plans)
    starts = np.concatenate([[0], np.cumsum(plans[:, 1])]).astype(np.int64)
    out = np.zeros(int(starts[-1]), np.uint8)
    (_write_all if compiled else _write_all_py)(v, codes, ks, plans, starts, out)
    return out, starts


# --- decoder (numpy) ----------------------------------------------------------------------------


def _bits(buf: NDArray[np.uint8], start_bit: NDArray[np.int64],
          width: NDArray[np.int64]) -> NDArray[np.int64]:
    """Values of ``width`` (<= 32) bits at ``start_bit`` of ``buf``, vectorized."""
    padded = np.concatenate([buf, np.zeros(8, np.uint8)])
    byte = start_bit >> 3
    word = np.zeros(len(start_bit), np.uint64)
    for b in range(5):  # 32 bits from any bit offset span at most 5 bytes
        word |= padded[byte + b].astype(np.uint64) << np.uint64(8 * b)
    word >>= (start_bit & 7).astype(np.uint64)
    mask = (np.uint64(1) << width.astype(np.uint64)) - np.uint64(1)
    return (word & mask).astype(np.int64)


def _unzigzag(u: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.asarray((u >> 1) ^ -(u & 1))


def decode_block(data: NDArray[np.uint8], field: str = "rotations") -> tuple[NDArray[np.float32], int]:
    """The first block in ``data``: its rotations ``(n, J, 4)`` xyzw float32, and its length."""
    if len(data) < HEADER:
        raise DeltaError(f"{field}: a delta block needs at least {HEADER} bytes, got {len(data)}")
    version, _, n, J, size, unary = _HEAD.unpack_from(data.tobytes()[:HEADER])
    if version != VERSION:
        raise DeltaError(f"{field}: delta block version {version}, this decoder reads {VERSION}")
    if not HEADER + J <= unary <= size <= len(data):
        raise DeltaError(f"{field}: a delta block of {size} bytes (unary at {unary}) does not fit "
                         f"the {len(data)} bytes given")
    block = data[:size]
    codes = block[HEADER:HEADER + J]
    T = 3 * J
    a = block[:unary]
    pos = 8 * (HEADER + J)
    heads = _bits(a, pos + 5 * np.arange(3 * T, dtype=np.int64), np.full(3 * T, 5, np.int64)).reshape(T, 3)
    ks, w0, w1 = heads[:, 0], heads[:, 1], heads[:, 2]
    pos += 15 * T
    widths = np.stack([w0, w1], 1).reshape(-1)
    at = pos + np.concatenate([[0], np.cumsum(widths)[:-1]])
    pos += int(widths.sum())
    firsts = _unzigzag(_bits(a, at, widths)).reshape(T, 2)
    stored = np.flatnonzero(ks != NO_RESIDUALS)
    m = max(n - 2, 0)
    count = len(stored) * m
    ones = np.flatnonzero(np.unpackbits(block[unary:], bitorder="little"))
    if len(ones) < count:
        raise DeltaError(f"{field}: the delta block ends before its {count} residuals")
    ones = ones[:count]
    quotient = np.diff(ones, prepend=-1) - 1
    k = np.repeat(ks[stored], m)
    escaped = quotient >= ESCAPE
    width = np.where(escaped, 32, k)
    starts = pos + np.concatenate([[0], np.cumsum(width)[:-1]]) if count else np.zeros(0, np.int64)
    if count and (starts[-1] + width[-1] > 8 * unary):
        raise DeltaError(f"{field}: the delta block's remainders run past their section")
    low = _bits(a, starts, width)
    u = np.where(escaped, low, (quotient << k) | low)
    changes = np.zeros((T, max(n - 1, 0)), np.int64)  # v[t] - v[t-1], t = 1..n-1
    if n > 1:
        changes[:, 0] = firsts[:, 1]
        res = np.zeros((T, m), np.int64)
        res[stored] = _unzigzag(u).reshape(len(stored), m)
        # r_t = v_t - 2 v_{t-1} + v_{t-2}: each change is the last plus the residual
        changes[:, 1:] = firsts[:, 1:2] + np.cumsum(res, axis=1)
    v = np.empty((T, n), np.int64)
    if n:
        v[:, 0] = firsts[:, 0]
        v[:, 1:] = firsts[:, :1] + np.cumsum(changes, axis=1)
    r = v.T.reshape(n, J, 3) * step_of(codes)[None, :, None]
    return quaternions(r), size


def decode(data: bytes | NDArray[np.uint8], field: str = "rotations") -> list[NDArray[np.float32]]:
    """Every block of a delta stream: per character its rotations ``(n, J, 4)``."""
    buf = np.frombuffer(data, np.uint8) if isinstance(data, (bytes, bytearray, memoryview)) else data
    out = []
    while len(buf):
        q, size = decode_block(buf, field)
        out.append(q)
        buf = buf[size:]
    return out
