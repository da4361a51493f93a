"""Live sessions on WebSocket ``/v1/stream``: a ``live`` message opens one (characters and
options), ``points`` messages bring every character's next trajectory points, ``finish`` ends
the trajectories. Parsing and checking here; the session loop is :mod:`service.batch_ws`'s."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from api_schemas import LiveRequest
from api_schemas.wire import WireError, unblob
from service.errors import ApiError
from service.jobs import ground_field, validate
from service.settings import Settings
from synth_core.runtime.bank import Bank
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.trajectory import TrajectoryError


def open_live(body: Any, settings: Settings, banks: dict[str, Bank]) -> tuple[LiveRequest, LiveShards]:
    """The session's request and synthesizer; 422 naming the field for anything unusable."""
    req = validate(LiveRequest, body, settings, banks)
    bank = banks[req.animal]
    if req.fps > bank.fps:
        raise ApiError(422, "fps", f"live points come at most at the library's {bank.fps:g} fps, "
                                   f"got {req.fps:g}")
    scales = np.array([np.nan if c.scale is None else c.scale for c in req.characters])
    seeds = np.array([-1 if c.seed is None else c.seed for c in req.characters], np.int64)
    try:
        live = LiveShards(bank, len(req.characters), req.fps, scales=scales, seed=req.seed, seeds=seeds,
                          scale_range=(req.scale_min, req.scale_max), sigma=req.sigma,
                          foot_lock=req.foot_lock, heading=req.heading, size_matching=req.size_matching,
                          tempo_spread=req.tempo_spread, ground=ground_field(req.ground),
                          reuse_windows=True)  # a window is packed before the next is made
    except TrajectoryError as exc:
        raise live_error(exc, "characters") from None
    return req, live


def live_error(exc: TrajectoryError, field: str) -> ApiError:
    """422 for ``field`` (``points``, ``characters``), at the character the problem is in."""
    message = str(exc.args[0]) if exc.args else str(exc)
    if exc.character is None:
        return ApiError(422, field, message)
    reason = message.split(": ", 1)[1] if message.startswith("character ") else message
    return ApiError(422, f"{field}[{exc.character}]", reason.removeprefix(f"{field}: "))


def points(body: dict[str, Any], n_characters: int, settings: Settings) -> NDArray[np.float64]:
    """The ``points`` of a points message: ``(characters, n, 3)`` float32/float64."""
    raw = body.get("points")
    if not isinstance(raw, dict):
        raise ApiError(422, "points", "a points message needs `points`: a blob (characters, n, 3)")
    dtype, shape = raw.get("dtype"), raw.get("shape")
    if not isinstance(shape, list) or not isinstance(raw.get("data"), bytes):
        raise ApiError(422, "points", "a blob needs `shape` (a list) and `data` (bytes)")
    if dtype not in ("<f4", "<f8"):
        raise ApiError(422, "points.dtype", f"points must be float32 ('<f4') or float64 ('<f8'), "
                                            f"got {dtype!r}")
    try:
        arr = unblob(dtype, shape, raw["data"], "points")
    except WireError as exc:
        raise ApiError(422, exc.field, exc.reason) from None
    if arr.ndim != 3 or arr.shape[0] != n_characters or arr.shape[2] != 3 or arr.shape[1] < 1:
        raise ApiError(422, "points.shape", f"expected ({n_characters}, n >= 1, 3): every character's "
                                            f"next points, got {tuple(arr.shape)}")
    if arr.shape[1] > settings.max_frames:
        raise ApiError(422, "points", f"{arr.shape[1]} points per character is over the limit of "
                                      f"{settings.max_frames} per message (max_frames)")
    return np.asarray(arr, np.float64)
