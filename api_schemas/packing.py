"""The compiled packers of the fixed-size rotation encodings, and the contacts bit mask.

Rotation packing is the response's biggest cost after synthesis (10 million quaternions for
500 characters x 500 frames), so s48 and i16 have compiled packers here, parallel over frames;
:mod:`api_schemas.wire` is their reference and the tests hold them to the same bytes. (The delta
encoding's compiled encoder is :mod:`api_schemas.delta`'s.) Wire layer: numpy and numba only,
no web or synthesis imports -- the service calls these.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from api_schemas.wire import S48_MAX, Encoding, encode_rotations

numba: Any
try:
    import numba
except ImportError:  # pragma: no cover - numba is a dependency; the numpy packer still works
    numba = None

_SQRT_HALF = np.float32(1.0 / np.sqrt(2.0))
_S48_SCALE = np.float32(S48_MAX / 2.0 / (1.0 / np.sqrt(2.0)))
_S48_MID = np.float32(S48_MAX / 2.0)


_ROUND = np.float32(2.0**23)  # x + 2**23 - 2**23 rounds 0 <= x < 2**23 half to even, as np.rint
_LANES = 64  # rotations per block: one AVX-512 vector per component row


def _pack_s48_block(q: Any, out: Any, lo: int, hi: int) -> None:  # pragma: no cover - compiled
    """s48 of rotations ``lo:hi`` of ``q`` (flat xyzw float32) into ``out`` (flat uint16, three
    per rotation: the 48-bit word's little-endian halves), as wire._pack_s48.

    A block of rotations is copied into component rows of a local array, packed there, copied
    out: with the arrays as given, LLVM cannot rule out that a store to ``out`` changes ``q``
    and keeps the loop scalar (3x slower, checked in the assembly). Selects, not branches, so
    the lanes run in step; the rounding is np.rint's without a call."""
    rows = np.empty((4, _LANES), np.float32)
    words = np.empty((3, _LANES), np.uint16)
    for start in range(lo, hi, _LANES):
        n = min(_LANES, hi - start)
        for k in range(n):
            for c in range(4):
                rows[c, k] = q[4 * (start + k) + c]
        for k in range(_LANES):
            x, y, z, w = rows[0, k], rows[1, k], rows[2, k], rows[3, k]
            ax, ay, az, aw = abs(x), abs(y), abs(z), abs(w)
            first, second = ay > ax, aw > az
            upper = (aw if second else az) > (ay if first else ax)
            big = (np.int32(2) + np.int32(second)) if upper else np.int32(first)
            largest = (w if second else z) if upper else (y if first else x)
            sign = np.float32(-1.0) if largest < 0 else np.float32(1.0)  # q and -q: one rotation
            k0 = (x if big > 0 else y) * sign  # the three components left, in order
            k1 = (y if big > 1 else z) * sign
            k2 = (z if big > 2 else w) * sign
            k0 = -_SQRT_HALF if k0 < -_SQRT_HALF else (_SQRT_HALF if k0 > _SQRT_HALF else k0)
            k1 = -_SQRT_HALF if k1 < -_SQRT_HALF else (_SQRT_HALF if k1 > _SQRT_HALF else k1)
            k2 = -_SQRT_HALF if k2 < -_SQRT_HALF else (_SQRT_HALF if k2 > _SQRT_HALF else k2)
            u0 = np.int32((k0 * _S48_SCALE + _S48_MID + _ROUND) - _ROUND)
            u1 = np.int32((k1 * _S48_SCALE + _S48_MID + _ROUND) - _ROUND)
            u2 = np.int32((k2 * _S48_SCALE + _S48_MID + _ROUND) - _ROUND)
            words[0, k] = np.uint16((big | (u0 << 2)) & 0xFFFF)  # bits 0-15
            words[1, k] = np.uint16(((u0 >> 14) | (u1 << 1)) & 0xFFFF)  # bits 16-31
            words[2, k] = np.uint16(u2)  # bits 32-47 (47 stays 0)
        for k in range(n):
            for c in range(3):
                out[3 * (start + k) + c] = words[c, k]


def _pack_s48_all(q: Any, out: Any) -> None:  # pragma: no cover - compiled
    n = q.shape[0] // 4
    blocks = 64
    step = ((n + blocks - 1) // blocks + _LANES - 1) // _LANES * _LANES
    for b in numba.prange(blocks):
        _pack_s48_block(q, out, min(n, b * step), min(n, (b + 1) * step))


def _pack_i16_rows(q: Any, out: Any) -> None:  # pragma: no cover - compiled
    for i in numba.prange(q.shape[0]):
        for c in range(4):
            out[i, c] = np.int16(np.rint(min(max(q[i, c], np.float32(-1.0)), np.float32(1.0))
                                         * np.float32(32767.0)))


if numba is not None:
    # No fastmath: the bytes must equal the numpy reference's, so no reassociation or FMA.
    _pack_s48_block = numba.njit(cache=True, nogil=True)(_pack_s48_block)
    _pack_s48_all = numba.njit(parallel=True, cache=True, nogil=True)(_pack_s48_all)
    _pack_i16_rows = numba.njit(parallel=True, cache=True, nogil=True)(_pack_i16_rows)


def pack_rotations(q: NDArray[np.float32], encoding: Encoding,
                   out: NDArray[Any] | None = None) -> NDArray[Any]:
    """:func:`api_schemas.wire.encode_rotations`, compiled where numba is installed; ``out``: a
    C-contiguous array of the packed shape and dtype to write into (s48 and i16)."""
    if numba is None or encoding == "f32":
        return encode_rotations(q, encoding)
    flat = np.ascontiguousarray(q, dtype=np.float32).reshape(-1)
    if encoding not in ("s48", "i16"):
        return encode_rotations(q, encoding)  # names the bad encoding
    shape = (*q.shape[:-1], 6 if encoding == "s48" else 4)
    dtype = np.uint8 if encoding == "s48" else np.int16
    if out is None:
        out = np.empty(shape, dtype)
    elif out.shape != shape or out.dtype != dtype or not out.flags.c_contiguous:
        raise ValueError(f"out: need a C-contiguous {np.dtype(dtype)} array of shape {shape}, "
                         f"got {out.dtype} {out.shape}")
    if encoding == "s48":
        _pack_s48_all(flat, out.reshape(-1).view(np.uint16))
    else:
        _pack_i16_rows(flat.reshape(-1, 4), out.reshape(-1, 4))
    return out


def contact_bits(contacts: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """(..., 4) bool -> (...,) uint8 mask: bit 0 LF, 1 RF, 2 LH, 3 RH."""
    return np.asarray((contacts.astype(np.uint8) << np.arange(4, dtype=np.uint8)).sum(-1), np.uint8)


