"""A synthesis request from wire dict to result: checked, padded to one batch, synthesized
(in a worker thread, cancellable between character chunks), cut back per character."""

from __future__ import annotations

import functools
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, TypeAdapter, ValidationError

from api_schemas import CharacterIn, LiveCharacter, LiveRequest, SynthesizeRequest
from api_schemas.models import GroundIn
from api_schemas.wire import WireError, unblob
from service.errors import ApiError, from_validation, problems_error
from service.settings import Settings
from synth_core.runtime.bank import Bank
from synth_core.runtime.parallel_render import Cancelled as Cancelled  # deadline passed, client left
from synth_core.runtime.streaming import BatchStream
from synth_core.runtime.synthesis import Options, Result
from synth_core.runtime.terrain import MAX_CELLS, HeightField, TerrainError
from synth_core.runtime.trajectory import FrameLimitError, Prepared, TrajectoryError, resampled_frames


@dataclass
class Job:
    request: SynthesizeRequest
    positions: NDArray[np.floating]  # (C, F_max, 3): shorter paths held at their last point
    lengths: list[int]  # each character's own point count
    cancel: threading.Event
    max_character_frames: int | None = None  # checked again once the resampling is known
    out_frames: int = 0  # frames each character comes back with at least (the longest's)
    ground: HeightField | None = None  # the request's terrain, checked

    @functools.cached_property
    def ids(self) -> list[str]:
        # Made once: callers index it per character (as a property, a list per lookup cost a
        # 500-character stream 10 ms before its first chunk).
        return [c.id for c in self.request.characters]


Checked = TypeVar("Checked", SynthesizeRequest, LiveRequest)


# Characters validated at a time: a body of 10,000 took 0.32 s in one pydantic call, which holds
# the GIL throughout -- in a decoding thread, /livez on the event loop still waited. Between
# slices the event loop gets its turn.
VALIDATE_SLICE = 256


@functools.cache
def _characters(model: type[BaseModel]) -> TypeAdapter[list[Any]]:
    item = CharacterIn if model is SynthesizeRequest else LiveCharacter
    return TypeAdapter(list[item])  # type: ignore[valid-type]


def validated_characters(model: type[BaseModel], characters: list[Any]) -> list[Any]:
    """``model``'s characters validated ``VALIDATE_SLICE`` at a time (422 naming the first problem)."""
    adapter, out = _characters(model), []
    for start in range(0, len(characters), VALIDATE_SLICE):
        try:
            out += adapter.validate_python(characters[start:start + VALIDATE_SLICE])
        except ValidationError as exc:
            raise problems_error(exc.errors(), "characters", start) from None
    return out


def validate(model: type[Checked], body: Any, settings: Settings, banks: dict[str, Bank]) -> Checked:
    """What a synthesize request and a live session share: a map within max_characters, the
    model's own checks, a loaded animal, a scale range, unique ids -- 422 naming the field."""
    if not isinstance(body, dict):
        raise ApiError(422, "body", f"expected an object (a map), got {type(body).__name__}")
    characters = body.get("characters")
    if isinstance(characters, list) and len(characters) > settings.max_characters:
        raise ApiError(422, "characters", f"{len(characters)} characters is over the limit of "
                                          f"{settings.max_characters} per request (max_characters)")
    if isinstance(characters, list) and len(characters) > VALIDATE_SLICE:
        body = {**body, "characters": validated_characters(model, characters)}
    try:
        req = model.model_validate(body)
    except ValidationError as exc:
        raise from_validation(exc) from None
    if req.animal not in banks:
        # 404 as for GET /v1/libraries/{animal}: the resource named is not here (docs/wire-format.md)
        raise ApiError(404, "animal", f"unknown animal {req.animal!r}; loaded: {', '.join(sorted(banks))}")
    if req.scale_min > req.scale_max:
        raise ApiError(422, "scale_min", f"must not exceed scale_max ({req.scale_min} > {req.scale_max})")
    seen: dict[str, int] = {}
    for i, ch in enumerate(req.characters):
        if ch.id in seen:
            raise ApiError(422, f"characters[{i}].id", f"{ch.id!r} is also character {seen[ch.id]}'s id")
        seen[ch.id] = i
    return req


def parse(body: Any, settings: Settings, banks: dict[str, Bank]) -> Job:
    """422 naming the field and the problem for anything the synthesis could not use."""
    req = validate(SynthesizeRequest, body, settings, banks)
    paths = []
    for i, ch in enumerate(req.characters):
        where = f"characters[{i}].points"
        if ch.points.dtype not in ("<f4", "<f8"):
            raise ApiError(422, f"{where}.dtype", f"points must be float32 ('<f4') or float64 ('<f8'), "
                                                  f"got {ch.points.dtype!r}")
        try:
            points = unblob(ch.points.dtype, ch.points.shape, ch.points.data, where)
        except WireError as exc:
            raise ApiError(422, exc.field, exc.reason) from None
        if points.ndim != 2 or points.shape[1] != 3:
            raise ApiError(422, f"{where}.shape", f"expected (frames, 3), got {tuple(points.shape)}")
        if len(points) < 2:
            raise ApiError(422, where, f"needs at least 2 points, got {len(points)}")
        if len(points) > settings.max_frames:
            raise ApiError(422, where, f"{len(points)} points is over the limit of {settings.max_frames} "
                                       f"per character (max_frames)")
        paths.append(points)
    lengths = [len(p) for p in paths]
    bank = banks[req.animal]
    # Counted at the library's frame rate and resampled at least min_resample_rate: that many
    # frames come back at least. A too-fast herd that asks for 'resample' may be resampled more
    # (up to 8x, see trajectory.MAX_RESAMPLE): checked again once that is known, before it is made.
    out_frames = resampled_frames(int(round((max(lengths) - 1) * bank.fps / req.fps)) + 1,
                                  req.min_resample_rate)
    total = out_frames * len(paths)
    if total > settings.max_character_frames:
        by = f" resampled {req.min_resample_rate:g}x (min_resample_rate)" if req.min_resample_rate > 1 else ""
        raise ApiError(422, "min_resample_rate" if by else "characters",
                       f"{len(paths)} characters x {out_frames} frames at {bank.fps:g} fps{by} = {total} "
                       f"character-frames is over the limit of {settings.max_character_frames} "
                       f"(max_character_frames)")
    # float32 points stay float32 (the synthesis widens them a few characters at a time, exactly):
    # half the fresh memory of a float64 copy of the batch.
    dtype = np.float32 if all(p.dtype == np.float32 for p in paths) else np.float64
    positions: NDArray[np.floating]
    if len(set(lengths)) == 1:
        positions = np.stack(paths).astype(dtype, copy=False)
    else:
        positions = np.empty((len(paths), max(lengths), 3), dtype)
        for c, p in enumerate(paths):
            positions[c, :len(p)] = p
            positions[c, len(p):] = p[-1]  # a shorter path: it stands at its end
    return Job(req, positions, lengths, threading.Event(), settings.max_character_frames, out_frames,
               ground_field(req.ground))


def ground_field(ground: GroundIn | None) -> HeightField | None:
    """The request's height field, checked: 422 naming the field (``ground.heights``, ...)."""
    if ground is None:
        return None
    where = "ground.heights"
    if ground.heights.dtype not in ("<f4", "<f8"):
        raise ApiError(422, f"{where}.dtype", f"heights must be float32 ('<f4') or float64 ('<f8'), "
                                              f"got {ground.heights.dtype!r}")
    if len(ground.heights.shape) != 2:
        raise ApiError(422, f"{where}.shape", f"expected (rows along z, columns along x), "
                                              f"got {tuple(ground.heights.shape)}")
    if int(np.prod(ground.heights.shape, dtype=np.int64)) > MAX_CELLS:
        raise ApiError(422, f"{where}.shape", f"{tuple(ground.heights.shape)} is over the limit of "
                                              f"{MAX_CELLS} heights")
    try:
        heights = unblob(ground.heights.dtype, ground.heights.shape, ground.heights.data, where)
        return HeightField.make(heights, ground.origin, ground.spacing)
    except WireError as exc:
        raise ApiError(422, exc.field, exc.reason) from None
    except TerrainError as exc:
        raise ApiError(422, exc.field, exc.reason) from None


def character_scales_and_seeds(req: SynthesizeRequest) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Given scales (NaN: draw one) and seeds (-1: from the request's), as synthesis takes them."""
    scales = np.array([np.nan if c.scale is None else c.scale for c in req.characters])
    seeds = np.array([-1 if c.seed is None else c.seed for c in req.characters], np.int64)
    return scales, seeds


def options(req: SynthesizeRequest, max_character_frames: int | None = None,
            ground: HeightField | None = None) -> Options:
    return Options(sigma=req.sigma, seed=req.seed, scale_range=(req.scale_min, req.scale_max),
                   skip_invalid=req.skip_invalid, foot_lock=req.foot_lock, first_index=req.first_index,
                   min_resample_rate=req.min_resample_rate, resample=req.resample,
                   size_matching=req.size_matching, tempo_spread=req.tempo_spread,
                   max_character_frames=max_character_frames, ground=ground, posed=posed(req))


def posed(req: SynthesizeRequest) -> NDArray[np.bool_]:
    """Each character's rotations are wanted, but a far one's (root_gait detail: its own, or the
    request's): the core makes those characters' root, gait and contacts alone."""
    return np.array([(c.detail or req.lod.detail) != "root_gait" for c in req.characters], np.bool_)


def trajectory_error(exc: TrajectoryError, job: Job) -> ApiError:
    if isinstance(exc, FrameLimitError):
        return ApiError(422, "characters", f"{exc} (max_character_frames): the paths need resampling "
                                           f"('resample' of a character faster than the library, or "
                                           f"min_resample_rate); "
                                           f"send fewer characters or frames per request")
    if exc.character is None:
        return ApiError(422, "characters", exc.reason)
    index = job.ids.index(str(exc.character)) if str(exc.character) in job.ids else -1
    part = "scale" if exc.reason.startswith("scale") else "points"
    return ApiError(422, f"characters[{index}].{part}", exc.reason.removeprefix("positions: "))


def open_stream(job: Job, bank: Bank, chunk_frames: int) -> BatchStream:
    """The job checked and prepared for streaming (in a worker thread); 422 as :func:`run`."""
    req = job.request
    scales, seeds = character_scales_and_seeds(req)
    try:
        return BatchStream(bank, job.positions, req.fps, scales,
                           options(req, job.max_character_frames, job.ground),
                           job.ids, seeds, chunk_frames)
    except TrajectoryError as exc:
        raise trajectory_error(exc, job) from None


def output_frames(job: Job, frames: int, kept: Iterable[int]) -> list[int]:
    """Each kept character's own frame count: its share of the common time axis of ``frames``."""
    longest = job.positions.shape[1]
    return [int(round((job.lengths[c] - 1) / (longest - 1) * (frames - 1))) + 1 for c in kept]


def skipped(job: Job, result: Result | BatchStream | Prepared) -> list[dict[str, Any]]:
    """The characters dropped (``skip_invalid``), as the answer lists them."""
    return notes(job, result.rejected)


def warned(job: Job, result: Result | BatchStream | Prepared) -> list[dict[str, Any]]:
    """The characters made whose motion could not keep their path, as the answer lists them."""
    return notes(job, result.warnings)


def notes(job: Job, found: dict[int, str]) -> list[dict[str, Any]]:
    return [{"id": job.ids[c], "index": c, "reason": why} for c, why in sorted(found.items())]
