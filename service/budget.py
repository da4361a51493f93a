"""A worker's memory budget for answers: each answer reserves its estimated size before it is
admitted, and gives it back when its last byte has left; one that does not fit now is refused
with 503 + Retry-After (another replica, or this one a moment later), one that could never fit
with 422 naming ``memory_budget_mb``.

The estimate (:func:`answer_bytes`) counts what an answer holds at its peak: its prepared paths,
and the larger of what preparing them takes and what streaming holds -- the pieces being rendered
and waiting in :mod:`synth_core.compiled.render_pool`, the bounded hand-over to the socket
(:mod:`service.pipe`) and the piece the socket is sending.
"""

from __future__ import annotations

import threading

from service.answer import characters_per_piece
from service.errors import ApiError
from service.prometheus import Metrics
from synth_core.compiled import render_pool
from synth_core.runtime.trajectory import ROWS

RETRY_AFTER_S = 1
MB = 1 << 20
PREPARED_BYTES = 24 + 24  # per character-frame: the smoothed float64 path, and the plan's columns
# Preparing the paths (retimed, smoothed: synth_core.runtime.trajectory, ROWS characters at a time) makes
# about four float64 copies of a row block's paths at once: traced, 229 MB at the peak of a
# 250 x 8,000 answer (its 48 MB of paths included), before any piece is made.
PREPARING_COPIES = 4
BYTES_PER_FRAME_BESIDE_ROTATIONS = 12 + 1 + 1  # root float32 xyz, gait, contact bits


def answer_bytes(characters: int, frames: int, joints: int, bytes_per_joint_frame: int,
                 as_json: bool, buffer_bytes: int, input_bytes: int = 0) -> int:
    """The estimated peak memory of an answer of ``characters`` x ``frames`` (frames made,
    resampling included) streamed with a hand-over of ``buffer_bytes``."""
    per_character = frames * (joints * bytes_per_joint_frame + BYTES_PER_FRAME_BESIDE_ROTATIONS)
    if as_json:
        per_character = per_character * 4 // 3 + 200  # base64, and the text around each blob
    per_piece = min(characters, characters_per_piece(frames, joints))
    rendered = per_piece * frames * joints * 16  # float32 rotations of one piece, while packed
    piece = per_piece * per_character
    threads = render_pool.size()
    held = (threads * (rendered + piece)  # being rendered and packed, one per render thread
            + 2 * threads * piece  # done, waiting their turn (render_pool.ordered runs ahead)
            + max(buffer_bytes, piece) + piece)  # handed over, and being sent
    preparing = PREPARING_COPIES * 24 * min(characters, ROWS) * frames  # before any piece
    return input_bytes + characters * frames * PREPARED_BYTES + max(held, preparing)


class MemoryBudget:
    def __init__(self, limit_mb: int, metrics: Metrics) -> None:
        self.limit = limit_mb * MB
        self.metrics = metrics
        self.used = 0
        self._lock = threading.Lock()  # reservations grow from pool threads once a batch is prepared

    def reserve(self, nbytes: int) -> Reservation:
        """``nbytes`` of the budget (503 when they do not fit now, 422 when they never could)."""
        reservation = Reservation(self)
        reservation.resize(nbytes)
        return reservation

    def _refusal(self, nbytes: int) -> ApiError:
        limit = self.limit // MB
        if nbytes > self.limit:
            return ApiError(422, "characters", f"this answer would hold about {nbytes / MB:.0f} MB of the "
                                               f"worker's memory, over its budget of {limit} MB "
                                               f"(memory_budget_mb): send fewer characters or frames "
                                               f"per request")
        self.metrics.rejected["memory"] += 1
        return ApiError(503, "", f"busy: answers in flight hold about {self.used / MB:.0f} MB of this "
                                 f"worker's memory budget of {limit} MB (memory_budget_mb); this one needs "
                                 f"{nbytes / MB:.0f} MB more; retry shortly",
                        headers={"Retry-After": str(RETRY_AFTER_S)})


class Reservation:
    """Part of a :class:`MemoryBudget`, held by one answer until :meth:`release`."""

    def __init__(self, budget: MemoryBudget) -> None:
        self.budget, self.nbytes = budget, 0

    def resize(self, nbytes: int) -> None:
        """Hold ``nbytes`` instead (growing: refused as :meth:`MemoryBudget.reserve`, and then the
        reservation is as it was)."""
        b = self.budget
        with b._lock:
            grow = nbytes - self.nbytes
            if grow > 0 and b.used + grow > b.limit:
                raise b._refusal(nbytes if nbytes > b.limit else grow)
            b.used += grow
            self.nbytes = nbytes
            b.metrics.memory_reserved = b.used

    def release(self) -> None:
        self.resize(0)
