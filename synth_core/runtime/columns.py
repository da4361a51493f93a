"""Per-character arrays ``(C, frames, ...)`` that grow at the end and drop frames at the front, as
a live session keeps its path, its plan and its feet (:mod:`synth_core.runtime.live`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth_core.runtime.plan import Floats, Plan


class Columns:
    """Frames ``[start, stop)`` of per-character arrays ``(C, frames, ...)`` with room to grow:
    new frames are written in place at the end and old ones dropped from the front (concatenating
    the whole of them for every block cost a tenth of a session's time)."""

    def __init__(self, C: int, layout: list[tuple[tuple[int, ...], type]], room: int = 0) -> None:
        self.C, self.layout = C, layout
        self.start = 0  # frame of the first kept
        self.lo = self.hi = 0  # the columns kept
        self.arrays = self._alloc(room)  # room: twice the frames usually kept, so moves are rare

    def _alloc(self, cap: int) -> list[NDArray[Any]]:
        return [np.empty((self.C, cap, *tail), dtype) for tail, dtype in self.layout]

    @property
    def frames(self) -> int:
        return self.hi - self.lo

    @property
    def stop(self) -> int:
        return self.start + self.frames

    def columns(self, a: int, b: int) -> list[NDArray[Any]]:
        """Frames ``[a, b)`` (within ``[start, stop)``) of each array: views."""
        i = self.lo - self.start
        return [x[:, a + i:b + i] for x in self.arrays]

    def reserve(self, n: int) -> list[NDArray[Any]]:
        """The next ``n`` frames, to be filled."""
        cap = self.arrays[0].shape[1]
        if self.hi + n > cap:  # move the kept frames to the front, into larger arrays if need be
            kept = self.hi - self.lo
            # In place when that leaves half the room free, or when the frames kept are no more
            # than those coming (a big block, as at the finish: the copy costs no more than the
            # writing; fresh arrays would cost page faults on top).
            in_place = kept + n <= cap // 2 or (kept + n <= cap and kept <= n)
            arrays = self.arrays if in_place else self._alloc(2 * (kept + n))
            for new, old in zip(arrays, self.arrays, strict=True):
                new[:, :kept] = old[:, self.lo:self.hi]
            self.arrays, self.lo, self.hi = arrays, 0, kept
        self.hi += n
        return self.columns(self.stop - n, self.stop)

    def drop_before(self, frame: int) -> None:
        frame = min(frame, self.stop)
        if frame > self.start:
            self.lo += frame - self.start
            self.start = frame


class PlannedColumns(Columns):
    """The planned frames kept (the foot lock's context): only those sent, every ``out_step``-th
    of the library's, its columns numbered by frame sent (library frame // out_step). Kept at
    the library's rate, each window's frames were a strided view, copied in strides for the
    render kernel (7% of a 30 fps session), and the plan's rows made for frames never read."""

    def __init__(self, scales: Floats, room: int) -> None:
        super().__init__(len(scales), [((4,), np.int32), ((3,), np.float32), ((), np.float64),
                                       ((3,), np.float64), ((4,), np.bool_), ((), np.bool_), ((), np.int8),
                                       ((), np.float64), ((2,), np.float64)],
                         room)
        self.scales = scales

    def _plan(self, arrays: list[NDArray[Any]]) -> Plan:
        rows, weights, yaw, path, contacts, stitches, gait, lean, way = arrays
        return Plan(rows, weights, yaw, path, self.scales, contacts, stitches, gait, lean, way)

    def plan(self) -> Plan:
        """The frames kept, ``[start, stop)``."""
        return self._plan(self.columns(self.start, self.stop))

    def reserve_plan(self, n: int) -> Plan:
        """The next ``n`` frames, to be filled."""
        return self._plan(self.reserve(n))
