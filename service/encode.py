"""What of a request's motion goes on the wire, and packed how: the encoding (f32, i16, s48,
delta) and the level of detail (per character: full, legs_spine, root_gait; per request: every
``frame_step``-th frame). The packing itself is the wire layer's (:mod:`api_schemas.packing`,
:mod:`api_schemas.delta`); this module only chooses rows, joints and frames and calls it."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from api_schemas import delta
from api_schemas.packing import pack_rotations
from api_schemas.wire import Encoding, packed_dtype
from synth_core.motion.lod import DETAILS, Detail, detail_joints
from synth_core.motion.skeleton import Skeleton


@dataclass(frozen=True, eq=False)
class Packing:
    """A request's (or live session's) choices, resolved per character (in the order of the
    characters sent: a batch's kept ones, a live session's)."""

    encoding: Encoding
    frame_step: int
    details: tuple[Detail, ...]
    skeleton: Skeleton
    scales: NDArray[np.floating]  # (C,) each character's scale: delta's steps depend on it
    default: Detail = "full"  # the request's lod.detail (a character's None)

    @property
    def plain(self) -> bool:
        """Every joint of every frame in a fixed-size encoding: the fast, in-place paths."""
        return self.encoding != "delta" and self.frame_step == 1 and all(d == "full" for d in self.details)

    def codes(self, rows: NDArray[np.int64] | slice) -> NDArray[np.uint8]:
        """delta's step codes ``(R, J)`` of these characters, by their scales."""
        return delta.joint_steps(self.skeleton.parents, self.skeleton.offsets, self.scales[rows])

    def joints(self, detail: Detail) -> NDArray[np.int64]:
        return detail_joints(self.skeleton, detail)

    @functools.cached_property
    def levels(self) -> NDArray[np.int8]:
        """``(C,)`` each character's detail, as its index in DETAILS: made once per packing (a
        live session's every chunk reads it; a loop over 100,000 details was 10 ms a chunk)."""
        index = {d: i for i, d in enumerate(DETAILS)}
        return np.array([index[d] for d in self.details], np.int8)


def packing(encoding: Encoding, frame_step: int, default: Detail, own: Sequence[Detail | None],
            skeleton: Skeleton, scales: NDArray[np.floating]) -> Packing:
    """``own``: each character's detail, None for the request's ``default``."""
    return Packing(encoding, frame_step, tuple(default if d is None else d for d in own), skeleton,
                   np.asarray(scales, np.float64), default)


def sent_frames(start: int, n: int, step: int) -> tuple[slice, int]:
    """Of frames ``[start, start + n)``, those on the ``step`` grid (frame % step == 0): which
    (a slice of the window) and the first's index at the reduced rate."""
    first = -(-start // step) * step
    return slice(first - start, n, step), first // step


def rotations(q: NDArray[np.floating], p: Packing, rows: NDArray[np.int64] | slice,
              joints: NDArray[np.int64] | None) -> tuple[NDArray[Any], dict[str, Any]]:
    """``q (R, n, J, 4)`` (the characters ``rows`` of the request, their frames chosen already)
    packed: the array whose bytes go out, and the rest of its ``rotations`` map (encoding,
    dtype, shape; delta's decoded_shape; the joints sent, when not all)."""
    if joints is not None:
        q = q[:, :, joints]
    meta: dict[str, Any] = {"encoding": p.encoding, "dtype": packed_dtype(p.encoding)}
    if p.encoding == "delta":
        packed, _ = delta.encode(q, p.codes(rows)[:, joints] if joints is not None else p.codes(rows))
        meta |= {"shape": [len(packed)], "decoded_shape": [*q.shape[:3], 4]}
    else:
        packed = pack_rotations(np.ascontiguousarray(q, np.float32), p.encoding)
        meta["shape"] = list(packed.shape)
    if joints is not None:
        meta["joints"] = [int(j) for j in joints]
    return packed, meta


def rotations_joined(parts: Sequence[tuple[NDArray[Any], dict[str, Any]]],
                     encoding: Encoding) -> tuple[NDArray[Any], dict[str, Any]]:
    """:func:`rotations` of consecutive groups of characters (the same frames and joints), each
    packed on its own, as one: the same bytes and map as one call on them all (delta's blocks
    are per character, one after another; the fixed-size encodings' rows are too)."""
    packed = np.concatenate([part for part, _ in parts])
    meta = dict(parts[0][1])
    if encoding == "delta":
        rows = sum(m["decoded_shape"][0] for _, m in parts)
        meta |= {"shape": [len(packed)], "decoded_shape": [rows, *meta["decoded_shape"][1:]]}
    else:
        meta["shape"] = list(packed.shape)
    return packed, meta


def rotations_each(q: NDArray[np.floating], p: Packing, rows: NDArray[np.int64],
                   joints: NDArray[np.int64] | None) -> list[tuple[NDArray[Any], dict[str, Any]]]:
    """:func:`rotations` of each character of ``q (R, n, J, 4)`` on its own (a REST answer's
    characters each carry their rotations), packed together: one encoder call for the group
    (delta's blocks are per character already: cut where each starts), the same bytes as a call
    per character."""
    if joints is not None:
        q = q[:, :, joints]
    meta: dict[str, Any] = {"encoding": p.encoding, "dtype": packed_dtype(p.encoding)}
    sent = {} if joints is None else {"joints": [int(j) for j in joints]}  # last, as rotations puts it
    if p.encoding == "delta":
        codes = p.codes(rows)
        packed, starts = delta.encode(q, codes[:, joints] if joints is not None else codes)
        bounds = starts.tolist()
        return [(packed[a:b], meta | {"shape": [b - a], "decoded_shape": [*q.shape[1:3], 4]} | sent)
                for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    whole = pack_rotations(np.ascontiguousarray(q, np.float32), p.encoding)
    return [(one, meta | {"shape": list(one.shape)} | sent) for one in whole]


def chunk_rows(p: Packing) -> tuple[NDArray[np.int64], NDArray[np.int64] | None]:
    """A chunk's rotation rows (characters not at root_gait) and its joints (None: all; the
    legs and spine when no row is at full detail)."""
    levels = p.levels
    rows = np.flatnonzero(levels != DETAILS.index("root_gait"))
    if not len(rows) or (levels[rows] == DETAILS.index("full")).any():
        return rows, None if len(rows) else np.zeros(0, np.int64)
    return rows, p.joints("legs_spine")
