"""Synthesis results to wire dicts (the shape of :class:`api_schemas.SynthesizeResponse`).

Rotation packing is the response's biggest cost after synthesis (10 million quaternions for
500 characters x 500 frames), so s48 and i16 have compiled packers here, parallel over frames;
:mod:`api_schemas.wire` is their reference and the tests hold them to the same bytes.
"""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
from numpy.typing import NDArray

from api_schemas.wire import S48_MAX, Encoding, blob, encode_rotations, packed_dtype
from synth_core.skeleton import Skeleton
from synth_core.synthesis import Result

numba: Any
try:
    import numba
except ImportError:  # pragma: no cover - numba is a dependency; the numpy packer still works
    numba = None

_SQRT_HALF = np.float32(1.0 / np.sqrt(2.0))
_S48_SCALE = np.float32(S48_MAX / 2.0 / (1.0 / np.sqrt(2.0)))
_S48_MID = np.float32(S48_MAX / 2.0)


def _pack_s48_rows(q: Any, out: Any) -> None:  # pragma: no cover - compiled
    """s48 of each row of ``q (n, 4)`` float32 into ``out (n, 6)`` uint8, as wire._pack_s48."""
    for i in numba.prange(q.shape[0]):
        a0, a1, a2, a3 = abs(q[i, 0]), abs(q[i, 1]), abs(q[i, 2]), abs(q[i, 3])
        first, second = a1 > a0, a3 > a2
        low = q[i, 1] if first else q[i, 0]
        high = q[i, 3] if second else q[i, 2]
        upper = abs(high) > abs(low)
        big = (2 + (1 if second else 0)) if upper else (1 if first else 0)
        sign = np.float32(-1.0) if (high if upper else low) < 0 else np.float32(1.0)
        word = np.uint64(big)
        k = 0
        for c in range(4):
            if c == big:
                continue
            v = min(max(q[i, c] * sign, -_SQRT_HALF), _SQRT_HALF)
            u = np.rint(v * _S48_SCALE + _S48_MID)
            word |= np.uint64(u) << np.uint64(2 + 15 * k)
            k += 1
        for b in range(6):
            out[i, b] = np.uint8((word >> np.uint64(8 * b)) & np.uint64(255))


def _pack_i16_rows(q: Any, out: Any) -> None:  # pragma: no cover - compiled
    for i in numba.prange(q.shape[0]):
        for c in range(4):
            out[i, c] = np.int16(np.rint(min(max(q[i, c], np.float32(-1.0)), np.float32(1.0))
                                         * np.float32(32767.0)))


if numba is not None:
    # No fastmath: the bytes must equal the numpy reference's, so no reassociation or FMA.
    _pack_s48_rows = numba.njit(parallel=True, cache=True, nogil=True)(_pack_s48_rows)
    _pack_i16_rows = numba.njit(parallel=True, cache=True, nogil=True)(_pack_i16_rows)


def pack_rotations(q: NDArray[np.float32], encoding: Encoding) -> NDArray[Any]:
    """:func:`api_schemas.wire.encode_rotations`, compiled where numba is installed."""
    if numba is None or encoding == "f32":
        return encode_rotations(q, encoding)
    flat = np.ascontiguousarray(q, dtype=np.float32).reshape(-1, 4)
    if encoding == "s48":
        out = np.empty((len(flat), 6), np.uint8)
        _pack_s48_rows(flat, out)
        return out.reshape(*q.shape[:-1], 6)
    if encoding == "i16":
        out16 = np.empty((len(flat), 4), np.int16)
        _pack_i16_rows(flat, out16)
        return out16.reshape(q.shape)
    return encode_rotations(q, encoding)  # names the bad encoding


def skeleton_id(animal: str, skeleton: Skeleton) -> str:
    """Changes whenever the joint layout a stream is played on does."""
    h = hashlib.sha256()
    h.update("|".join(skeleton.names).encode())
    h.update(np.ascontiguousarray(skeleton.parents, np.int64).tobytes())
    h.update(np.ascontiguousarray(skeleton.offsets, np.float32).tobytes())
    return f"{animal}-{h.hexdigest()[:12]}"


def contact_bits(contacts: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """(..., 4) bool -> (...,) uint8 mask: bit 0 LF, 1 RF, 2 LH, 3 RH."""
    return np.asarray((contacts.astype(np.uint8) << np.arange(4, dtype=np.uint8)).sum(-1), np.uint8)


def characters_out(result: Result, ids: list[str], frames: list[int],
                   encoding: Encoding) -> list[dict[str, Any]]:
    """Per kept character, its wire dict; ``frames``: each one's own frame count (characters
    padded to a common length are cut back to it)."""
    packed = pack_rotations(result.rotations, encoding)
    bits = contact_bits(result.contacts)
    out = []
    for c, (cid, n) in enumerate(zip(ids, frames, strict=True)):
        rot = blob(packed[c, :n])
        rot["encoding"] = encoding
        rot["dtype"] = packed_dtype(encoding)
        out.append({"id": cid, "scale": float(result.scales[c]), "frames": n,
                    "root": blob(result.root_pos[c, :n]), "rotations": rot,
                    "gait": blob(result.gait[c, :n]), "contacts": blob(bits[c, :n])})
    return out
