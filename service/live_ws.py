"""Live sessions on WebSocket ``/v1/stream``: a ``live`` message opens one (characters and
options), ``points`` messages bring every character's next trajectory points, ``finish`` ends
the trajectories. Parsing and checking, and the session's loop (:func:`stream_live`) on the
connection's :class:`service.ws_session.Session`."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from api_schemas import LiveRequest
from api_schemas.models import DETAILS, GroundIn
from api_schemas.wire import WireError, unblob
from service import encode
from service.chunk import packed_chunk
from service.encode import Packing
from service.errors import ApiError, from_validation
from service.jobs import ground_field, validate
from service.packing import skeleton_id
from service.settings import Settings
from service.ws_session import Session
from synth_core.runtime.bank import Bank
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.streaming import Window
from synth_core.runtime.terrain import HeightField
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
                          latency_ms=req.budget_ms,
                          reuse_windows=True)  # a window is packed before the next is made
    except TrajectoryError as exc:
        raise live_error(exc, "characters") from None
    return req, live


def new_details(p: Packing, body: dict[str, Any]) -> Packing:
    """A ``lod`` message's ``details``: every character's level of detail from the next chunk on
    (None: the session's ``lod.detail``); 422 naming the field for anything else."""
    details = body.get("details")
    C = len(p.details)
    if not isinstance(details, list) or len(details) != C:
        raise ApiError(422, "details", f"a lod message needs `details`: a list of {C} levels of detail "
                                       f"(one per character, null for the session's), got {details!r:.80}")
    for i, d in enumerate(details):
        if d is not None and d not in DETAILS:
            raise ApiError(422, f"details[{i}]",
                           f"must be one of {', '.join(DETAILS)} or null, got {d!r:.40}")
    return replace(p, details=tuple(p.default if d is None else d for d in details))


def posed(p: Packing) -> NDArray[np.bool_]:
    """The characters whose rotations are sent (all but those at root_gait): the others are not
    posed at all (:meth:`synth_core.runtime.live.LiveSynth.set_posed`)."""
    return np.asarray(p.levels != DETAILS.index("root_gait"))


def new_ground(body: dict[str, Any]) -> HeightField | None:
    """A ``ground`` message's height field (null: the points' y from now on); 422 naming the
    field (``ground.heights``, ...) as for the session's opening ``ground``."""
    if "ground" not in body:
        raise ApiError(422, "ground", "a ground message needs `ground`: a height field "
                                      "{heights, origin, spacing} or null (docs/terrain.md)")
    if body["ground"] is None:
        return None
    try:
        ground = GroundIn.model_validate(body["ground"])
    except ValidationError as exc:
        raise from_validation(exc, "ground") from None
    return ground_field(ground)


def live_error(exc: TrajectoryError, field: str) -> ApiError:
    """422 for ``field`` (``points``, ``characters``; ``velocity`` where the reason names it), at
    the character the problem is in."""
    if exc.reason.startswith("velocity: "):  # a points message's velocity, checked with its points
        field = "velocity"
    if exc.character is None:
        return ApiError(422, field, exc.reason)
    return ApiError(422, f"{field}[{exc.character}]", exc.reason.removeprefix(f"{field}: "))


def _float_blob(body: dict[str, Any], name: str, what: str) -> NDArray[np.floating]:
    """A points message's float32/float64 blob ``name`` (``what``: its shape, for the error)."""
    raw = body.get(name)
    if not isinstance(raw, dict):
        raise ApiError(422, name, f"`{name}` must be a blob {what}")
    dtype, shape = raw.get("dtype"), raw.get("shape")
    if not isinstance(shape, list) or not isinstance(raw.get("data"), bytes):
        raise ApiError(422, name, "a blob needs `shape` (a list) and `data` (bytes)")
    if dtype not in ("<f4", "<f8"):
        raise ApiError(422, f"{name}.dtype", f"{name} must be float32 ('<f4') or float64 ('<f8'), "
                                             f"got {dtype!r}")
    try:
        return unblob(dtype, shape, raw["data"], name)
    except WireError as exc:
        raise ApiError(422, exc.field, exc.reason) from None


def points(body: dict[str, Any], n_characters: int, settings: Settings) -> NDArray[np.float64]:
    """The ``points`` of a points message: ``(characters, n, 3)`` float32/float64."""
    if not isinstance(body.get("points"), dict):
        raise ApiError(422, "points", "a points message needs `points`: a blob (characters, n, 3)")
    arr = _float_blob(body, "points", "(characters, n, 3)")
    if arr.ndim != 3 or arr.shape[0] != n_characters or arr.shape[2] != 3 or arr.shape[1] < 1:
        raise ApiError(422, "points.shape", f"expected ({n_characters}, n >= 1, 3): every character's "
                                            f"next points, got {tuple(arr.shape)}")
    if arr.shape[1] > settings.max_frames:
        raise ApiError(422, "points", f"{arr.shape[1]} points per character is over the limit of "
                                      f"{settings.max_frames} per message (max_frames)")
    return np.asarray(arr, np.float64)


def velocity(body: dict[str, Any], shape: tuple[int, ...]) -> NDArray[np.float64] | None:
    """A points message's optional ``velocity`` (None if not sent): ``(characters, n, 2)``, each
    point's ground velocity (x, z, m/s); its values are checked with the points (LiveSynth.check)."""
    if body.get("velocity") is None:
        return None
    arr = _float_blob(body, "velocity", "(characters, n, 2)")
    want = (shape[0], shape[1], 2)
    if arr.shape != want:
        raise ApiError(422, "velocity.shape", f"expected {want}: x and z (m/s) of every point sent, "
                                              f"got {tuple(arr.shape)}")
    return np.asarray(arr, np.float64)


def appending(synth: LiveShards, body: dict[str, Any], n_characters: int,
              settings: Settings) -> Callable[[], list[Window] | None]:
    """A points message's step: its points (and velocity, if sent) appended, a window's frames taken."""
    arr = points(body, n_characters, settings)
    return functools.partial(synth.append, arr, synth.window_frames, velocity(body, arr.shape))


class LiveRun:
    """One live session on a connection: its synthesizer, the chunk being sent while the next
    is made, and the scratch pages its chunks are packed into."""

    def __init__(self, s: Session, number: int, req: LiveRequest, synth: LiveShards, p: Packing) -> None:
        self.s, self.number, self.req, self.synth, self.p = s, number, req, synth, p
        self.C = len(req.characters)
        # Windows of at most a segment's frames: a finish (or a long points message) settling
        # more comes as several chunks, each window rendered and packed over the last's pages
        # (fresh pages, zeroed by the OS as they are first written, took a fifth of the server's
        # CPU in a live session: perf) -- and over an earlier session's (see Shelf).
        self.scratch = s.state.scratches.take()
        self.stepping = False  # a step may be writing into scratch
        # A chunk goes out while the next is synthesized (a live tick of 4,000 horses is ~30 MB:
        # sending it took a third as long as making it, the cores half idle meanwhile).
        self.sending: asyncio.Future[None] | None = None
        self.sent = 0

    def step(self, advance: Callable[[], list[Window] | None], index: int) -> tuple[int, memoryview] | None:
        """In the pool: the next chunk, of the windows ``advance`` gives (then of those left);
        None when there are none."""
        windows = advance()
        while windows is not None and windows[0].stop <= windows[0].start:  # no frame sent in it
            windows = self.synth.take(self.synth.window_frames)
        if windows is None:
            return None
        # Two buffers in turn: one is sent while the next is packed.
        return packed_chunk(self.number, index, windows, self.req.encoding, self.scratch,
                            f"chunk{index % 2}", self.p)

    async def made(self, advance: Callable[[], list[Window] | None]) -> tuple[int, memoryview] | None:
        t0 = time.perf_counter()
        self.stepping = True
        try:
            made: tuple[int, memoryview] | None = await self.s.in_pool(self.step, advance, self.sent)
        except TrajectoryError as exc:
            self.stepping = False
            raise live_error(exc, "points") from None
        self.stepping = False
        self.s.state.metrics.synthesis_seconds += time.perf_counter() - t0
        return made

    async def tick(self, advance: Callable[[], list[Window] | None]) -> None:
        """One points (or finish) message's chunks, each sent while the next is made."""
        s = self.s
        while True:
            made = await self.made(advance)
            if self.sending is not None:
                await self.sending  # in order, and its failure (a slow consumer) raised here
                self.sending = None
            if made is None:
                return
            await s.wait_for_room(self.sent)
            s.check()
            self.sending = asyncio.ensure_future(s.send(made[1]))
            s.state.metrics.character_frames += self.C * made[0]
            self.sent += 1
            advance = functools.partial(self.synth.take, self.synth.window_frames)

    async def run(self) -> None:
        """Until finish (or the client cancels or leaves)."""
        s, synth, W = self.s, self.synth, self.synth.window_frames
        while True:
            message = await s.next_live()
            if message is None:  # before its finish: the client cancelled or left
                s.state.metrics.cancelled += 1
                return
            if message.get("type") == "lod":  # the characters' details from the next chunk on
                self.p = new_details(self.p, message)
                synth.set_posed(posed(self.p))
                continue
            if message.get("type") == "ground":  # the terrain of the frames rendered from now on
                synth.set_ground(new_ground(message))
                continue
            finishing = message.get("type") == "finish"
            await self.tick(functools.partial(synth.finish, W) if finishing else
                            appending(synth, message, self.C, s.settings))
            if finishing:
                return

    async def settle(self) -> None:
        """The last chunk's send waited for; on an error, let it finish first (that error wins).
        The scratch goes back for the next session unless a step or a send may still be using
        it (this coroutine cancelled while one ran; the pool thread goes on): then left to the GC."""
        if self.sending is not None:
            with contextlib.suppress(Exception):
                await self.sending
        if not self.stepping and (self.sending is None or self.sending.done()):
            self.s.state.scratches.give(self.scratch)


def _start_message(s: Session, number: int, req: LiveRequest, synth: LiveShards,
                   p: Packing) -> dict[str, Any]:
    registry = s.state.registry
    fps = registry.banks[req.animal].fps
    return {"type": "start", "batch": number, "mode": "live", "animal": req.animal,
            "skeleton_id": skeleton_id(req.animal, registry.libraries[req.animal].skeleton),
            "fps": fps / synth.out_step / p.frame_step, "library_fps": fps,
            "frame_step": p.frame_step, "encoding": req.encoding, "details": list(p.details),
            "joints": registry.banks[req.animal].skeleton.n_joints, "resample_rate": 1.0,
            "latency_mode": "exact" if req.budget_ms is None else "low_latency",
            "latency_ms": req.budget_ms,
            "latency_frames": -(-synth.latency_frames // synth.out_step),
            "latency_s": synth.latency_frames / fps,
            "characters": [{"id": c.id, "scale": float(h)}
                           for c, h in zip(req.characters, synth.scales, strict=True)]}


async def stream_live(s: Session, body: dict[str, Any]) -> None:
    """A ``live`` message: start, frames for the points as they come until finish, end."""
    number = s.begin()
    req, synth = open_live(body, s.settings, s.state.registry.banks)
    bank = s.state.registry.banks[req.animal]
    p = encode.packing(req.encoding, req.lod.frame_step, req.lod.detail,
                       [c.detail for c in req.characters], bank.skeleton, synth.scales)
    synth.set_posed(posed(p))
    await s.send(_start_message(s, number, req, synth, p))
    s.started()
    run = LiveRun(s, number, req, synth, p)
    try:
        await run.run()
        if run.sending is not None:
            last, run.sending = run.sending, None
            await last
    finally:
        await run.settle()
    s.live_open = False
    s.drop_inbox()
    await s.end(number, run.sent)
