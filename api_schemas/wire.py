"""The binary wire format: arrays as little-endian blobs, rotations packed three ways.

An array travels as ``{"dtype": "<f4", "shape": [F, 3], "data": <bytes>}`` -- msgpack ``bin``
in msgpack bodies, base64 text in JSON ones (:mod:`api_schemas.models` does that switch). Only
the dtypes in ``DTYPES`` are accepted; ``data`` must hold exactly ``prod(shape)`` items.

Rotations (unit quaternions, xyzw) in one of four encodings, chosen per request:

- ``f32``: xyzw float32, 16 bytes per joint-frame, lossless.
- ``i16``: xyzw as normalized int16 (``round(x * 32767)``, glTF's normalized SHORT,
  KHR_mesh_quantization), 8 bytes.
- ``s48``: smallest three, 6 bytes: the largest component is dropped (its sign made positive:
  q and -q are one rotation) and rebuilt from unit norm; bits 0-1 say which it was, bits 2-16,
  17-31, 32-46 the other three in order, each mapped from [-1/sqrt 2, 1/sqrt 2] to 0 .. 32767;
  bit 47 is 0. Stored as the low 6 bytes of that little-endian 48-bit integer.
- ``delta``: time-axis deltas of per-joint quantized rotation vectors, Rice coded, ~1.3-1.9
  bytes, every joint's world position within 0.1 mm (:mod:`api_schemas.delta`): ``|u1 (nbytes,)``,
  one block per character; the blob's ``decoded_shape`` says what it decodes to.

i16 decoding renormalizes; s48 rebuilds a unit quaternion. ``ENCODING_ERROR`` is the measured worst case
(:func:`worst_error`, on a million random rotations; ``tests/test_wire.py`` checks it).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

MSGPACK = "application/vnd.msgpack"  # the media type of msgpack bodies (two aliases also accepted)
Encoding = Literal["f32", "i16", "s48", "delta"]
ENCODINGS: tuple[Encoding, ...] = ("f32", "i16", "s48", "delta")
FIXED_ENCODINGS: tuple[Encoding, ...] = ("f32", "i16", "s48")  # a fixed size per joint-frame
BYTES_PER_JOINT_FRAME = {"f32": 16, "i16": 8, "s48": 6}
# delta's size depends on the motion: measured 1.34-1.92 (bench/bench_wire.py); budgets use this.
DELTA_BYTES_PER_JOINT_FRAME = 2.0
DTYPES = ("<f4", "<f8", "<i2", "<i4", "|i1", "|u1")
S48_MAX = 32767  # 15 bits
_SQRT_HALF = 1.0 / math.sqrt(2.0)
POINT_DISTANCE_M = 0.03  # the documented error is also given as displacement of a point 3 cm away

# Worst case over 1,000,000 random unit quaternions (worst_error): (degrees, mm at 3 cm).
ENCODING_ERROR: dict[str, tuple[float, float]] = {
    "f32": (0.0, 0.0),  # the float32 the synthesis makes, bit for bit
    "i16": (0.0035, 0.0019),  # measured 0.00343 deg, 0.00180 mm
    "s48": (0.0075, 0.0040),  # measured 0.00749 deg, 0.00393 mm
}


class WireError(ValueError):
    """An array or packed stream that cannot be decoded; ``field`` names where it was."""

    def __init__(self, message: str, field: str = "") -> None:
        super().__init__(f"{field}: {message}" if field else message)
        self.field = field
        self.reason = message


def blob(array: NDArray[Any]) -> dict[str, Any]:
    """An array as a wire blob (little-endian, C order)."""
    a = np.ascontiguousarray(array)
    dtype = a.dtype.newbyteorder("<") if a.dtype.byteorder == ">" else a.dtype
    a = a.astype(dtype, copy=False)
    return {"dtype": dtype.str, "shape": list(a.shape), "data": a.tobytes()}


def unblob(dtype: str, shape: list[int], data: bytes, field: str = "") -> NDArray[Any]:
    """A wire blob back to an array, refusing what does not add up."""
    if dtype not in DTYPES:
        raise WireError(f"dtype must be one of {', '.join(DTYPES)}, got {dtype!r}", f"{field}.dtype")
    if any(not isinstance(n, int) or n < 0 for n in shape) or len(shape) > 4:
        raise WireError(f"shape must be at most 4 non-negative integers, got {shape}", f"{field}.shape")
    dt = np.dtype(dtype)
    count = math.prod(shape)
    if len(data) != count * dt.itemsize:
        raise WireError(f"{len(data)} bytes do not hold {dtype} of shape {shape} "
                        f"({count * dt.itemsize} bytes)", f"{field}.data")
    return np.frombuffer(data, dtype=dt).reshape(shape)


# --- rotation encodings -------------------------------------------------------------------------

def encode_rotations(q: NDArray[np.floating], encoding: Encoding) -> NDArray[Any]:
    """``q (..., 4)`` unit xyzw -> f32 ``(..., 4)``, i16 ``(..., 4)`` or s48 ``(..., 6)`` uint8.
    (delta needs each character's joint steps: :func:`api_schemas.delta.encode`.)"""
    q = np.asarray(q, dtype=np.float32)
    if encoding == "f32":
        return q
    if encoding == "i16":
        return np.asarray(np.rint(np.clip(q, -1.0, 1.0) * 32767.0), dtype="<i2")
    if encoding == "s48":
        return _pack_s48(q)
    raise WireError(f"must be one of {', '.join(ENCODINGS)}, got {encoding!r}", "encoding")


def decode_rotations(packed: NDArray[Any], encoding: Encoding) -> NDArray[np.float32]:
    """The inverse of :func:`encode_rotations`: unit xyzw float32 ``(..., 4)``."""
    if encoding == "f32":
        return np.asarray(packed, dtype=np.float32)
    if encoding == "i16":
        q = np.maximum(np.asarray(packed, dtype=np.float32) / 32767.0, -1.0)
        return _unit(q)
    if encoding == "s48":
        return _unpack_s48(np.asarray(packed, dtype=np.uint8))
    if encoding == "delta":
        from api_schemas import delta

        try:
            blocks = delta.decode(np.asarray(packed, np.uint8).reshape(-1))
        except (delta.DeltaError, ValueError) as exc:
            raise WireError(str(exc), "rotations") from None
        try:
            return np.stack(blocks) if blocks else np.zeros((0, 0, 0, 4), np.float32)
        except ValueError:
            raise WireError("delta blocks of different frames or joints", "rotations") from None
    raise WireError(f"must be one of {', '.join(ENCODINGS)}, got {encoding!r}", "encoding")


def packed_dtype(encoding: Encoding) -> str:
    return {"f32": "<f4", "i16": "<i2", "s48": "|u1", "delta": "|u1"}[encoding]


def rotations_of(rotations: dict[str, Any], n_joints: int | None = None, n_characters: int | None = None,
                 field: str = "rotations") -> NDArray[np.float32]:
    """A response's ``rotations`` map (blob + ``encoding``, delta's ``decoded_shape``) -> unit
    xyzw float32: ``(frames, joints, 4)`` of a REST character, ``(C, n, joints, 4)`` of a chunk.
    A level of detail's map sends some ``joints`` (of ``n_joints``) and, in a chunk, some
    ``characters`` (rows, of ``n_characters``): given the counts, the rest are filled in with
    the identity rotation."""
    encoding = rotations.get("encoding")
    if encoding not in ENCODINGS:
        raise WireError(f"must be one of {', '.join(ENCODINGS)}, got {encoding!r}", f"{field}.encoding")
    packed = unblob(rotations["dtype"], rotations["shape"], rotations["data"], field)
    q = decode_rotations(packed, encoding)
    if encoding == "delta":
        shape = rotations.get("decoded_shape")
        if not isinstance(shape, list) or math.prod(shape) != q.size:
            raise WireError(f"decoded_shape {shape!r} does not hold the {q.shape} decoded",
                            f"{field}.decoded_shape")
        q = q.reshape(shape)
    joints, rows = rotations.get("joints"), rotations.get("characters")
    if joints is not None and n_joints is not None:
        full = np.zeros((*q.shape[:-2], n_joints, 4), np.float32)
        full[..., 3] = 1.0
        full[..., joints, :] = q
        q = full
    if rows is not None and n_characters is not None:
        full = np.zeros((n_characters, *q.shape[1:]), np.float32)
        full[..., 3] = 1.0
        full[rows] = q
        q = full
    return q


def _unit(q: NDArray[np.float32]) -> NDArray[np.float32]:
    n = np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]
    return np.asarray(q / np.maximum(n, np.float32(1e-30)), dtype=np.float32)


def _pack_s48(q: NDArray[np.float32]) -> NDArray[np.uint8]:
    lead = q.shape[:-1]
    cols = np.ascontiguousarray(q.reshape(-1, 4).T)  # (4, n): component rows, cheap to pick from
    # The largest |component| by pairwise comparisons (argmax over a 4-row axis is 10x slower).
    first, second = np.abs(cols[1]) > np.abs(cols[0]), np.abs(cols[3]) > np.abs(cols[2])
    low, high = np.where(first, cols[1], cols[0]), np.where(second, cols[3], cols[2])
    upper = np.abs(high) > np.abs(low)
    big = np.where(upper, second.astype(np.int8) + np.int8(2), first.astype(np.int8))
    # q and -q are one rotation: flip so the dropped component is positive.
    cols *= np.where(np.where(upper, high, low) < 0, np.float32(-1), np.float32(1))
    scale = np.float32(S48_MAX / 2.0 / _SQRT_HALF)
    word = big.astype(np.uint64)
    for k, shift in enumerate((2, 17, 32)):
        kept = np.where(big > k, cols[k], cols[k + 1])  # the k-th component left after dropping one
        u = np.rint(np.clip(kept, -_SQRT_HALF, _SQRT_HALF) * scale + np.float32(S48_MAX / 2.0))
        word |= u.astype(np.uint64) << np.uint64(shift)
    out = word.astype("<u8").view(np.uint8).reshape(-1, 8)[:, :6]
    return np.ascontiguousarray(out).reshape(*lead, 6)


def _unpack_s48(packed: NDArray[np.uint8]) -> NDArray[np.float32]:
    if packed.shape[-1:] != (6,):
        raise WireError(f"s48 rotations need a last axis of 6 bytes, got shape {packed.shape}")
    lead = packed.shape[:-1]
    wide = np.zeros((math.prod(lead), 8), np.uint8)
    wide[:, :6] = packed.reshape(-1, 6)
    word = wide.view("<u8")[:, 0]
    big = (word & np.uint64(3)).astype(np.int8)
    mask = np.uint64(S48_MAX)
    step = np.float32(_SQRT_HALF / (S48_MAX / 2.0))
    rest = [((word >> np.uint64(shift)) & mask).astype(np.float32) * step - np.float32(_SQRT_HALF)
            for shift in (2, 17, 32)]
    dropped = np.sqrt(np.maximum(1.0 - (rest[0] ** 2 + rest[1] ** 2 + rest[2] ** 2), 0.0))
    q = np.empty((len(word), 4), np.float32)
    for k in range(4):
        before = rest[k - 1] if k > 0 else dropped  # component k when the dropped one came before it
        after = rest[k] if k < 3 else dropped
        q[:, k] = np.where(big == k, dropped, np.where(big < k, before, after))
    return q.reshape(*lead, 4)  # unit already: the dropped component is rebuilt from the norm


def rotation_angle(a: NDArray[np.floating], b: NDArray[np.floating]) -> NDArray[np.float64]:
    """Radians between rotations ``a`` and ``b`` (..., 4): 2 atan2(|vector part|, |w|) of
    conj(a) b, exact for small angles (arccos of the dot product is not). Written out rather than
    quat.angle(quat.mul(quat.inv(a), b)): this form is exactly 0 for equal inputs, which the
    lossless f32 encoding's documented error of 0 relies on."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    w = np.sum(a * b, axis=-1)
    v = (a[..., 3:4] * b[..., :3] - b[..., 3:4] * a[..., :3] - np.cross(a[..., :3], b[..., :3]))
    return np.asarray(2.0 * np.arctan2(np.linalg.norm(v, axis=-1), np.abs(w)))


def worst_error(encoding: Encoding, n: int = 1_000_000, seed: int = 0) -> tuple[float, float]:
    """Measured worst case over ``n`` random unit quaternions: (degrees, mm of a point 3 cm away)."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    back = decode_rotations(encode_rotations(q, encoding), encoding).astype(np.float64)
    angle = rotation_angle(q, back)  # against the float32 the caller had
    degrees = float(np.degrees(angle.max()))
    return degrees, float(2.0 * POINT_DISTANCE_M * np.sin(angle.max() / 2.0) * 1000.0)
