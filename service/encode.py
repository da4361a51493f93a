"""What of a request's motion goes on the wire, and packed how: the encoding (f32, i16, s48,
delta) and the level of detail (per character: full, legs_spine, root_gait; per request: every
``frame_step``-th frame). The packing itself is the wire layer's (:mod:`api_schemas.packing`,
:mod:`api_schemas.delta`); this module only chooses rows, joints and frames and calls it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from api_schemas import delta
from api_schemas.packing import pack_rotations
from api_schemas.wire import Encoding, packed_dtype
from synth_core.motion.lod import Detail, detail_joints
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


def chunk_rows(p: Packing) -> tuple[NDArray[np.int64], NDArray[np.int64] | None]:
    """A chunk's rotation rows (characters not at root_gait) and its joints (None: all; the
    legs and spine when no row is at full detail)."""
    rows = np.array([c for c, d in enumerate(p.details) if d != "root_gait"], np.int64)
    details = {p.details[c] for c in rows}
    if not details or "full" in details:
        return rows, None if details else np.zeros(0, np.int64)
    return rows, p.joints("legs_spine")
