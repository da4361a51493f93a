"""A batch on WebSocket ``/v1/stream``: its motion in chunks of K frames, each sent as soon as it
is made (docs/streaming.md). The connection and its protocol: :mod:`service.ws_session`; live
sessions on the same connection: :mod:`service.live_ws`."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Iterator
from typing import Any

from fastapi import WebSocket

from service import encode, jobs, live_ws, ws_session
from service.chunk import packed_chunk
from service.errors import ApiError
from service.packing import skeleton_id
from service.state import State
from service.ws_session import Session
from synth_core.runtime.streaming import BatchStream, Window

MAX_CHUNK_FRAMES = 600


def _chunk_frames(body: dict[str, Any], default: int) -> int:
    chunk_frames = body.pop("chunk_frames", default)
    body.pop("type", None)
    if (not isinstance(chunk_frames, int) or isinstance(chunk_frames, bool)
            or not 1 <= chunk_frames <= MAX_CHUNK_FRAMES):
        raise ApiError(422, "chunk_frames", f"must be an integer from 1 to {MAX_CHUNK_FRAMES}, "
                                            f"got {chunk_frames!r}")
    return chunk_frames


async def _open(s: Session, job: jobs.Job, chunk_frames: int) -> BatchStream:
    """The batch checked and prepared in the pool (refused, 503 -> 1013, when it is full)."""
    bank = s.state.registry.banks[job.request.animal]
    release = await s.pool_slot(s.state.admission.admit)
    try:
        stream: BatchStream = await asyncio.get_running_loop().run_in_executor(
            s.state.pool, jobs.open_stream, job, bank, chunk_frames)
    finally:
        release()
    return stream


def _start(s: Session, number: int, job: jobs.Job, stream: BatchStream, chunk_frames: int,
           count: int, p: encode.Packing) -> dict[str, Any]:
    req, registry = job.request, s.state.registry
    frames = jobs.output_frames(job, stream.frames, stream.kept)
    ids = [job.ids[c] for c in stream.kept]
    return {"type": "start", "batch": number, "animal": req.animal,
            "skeleton_id": skeleton_id(req.animal, registry.libraries[req.animal].skeleton),
            "fps": registry.banks[req.animal].fps / p.frame_step, "frame_step": p.frame_step,
            "encoding": req.encoding, "details": list(p.details),
            "joints": registry.banks[req.animal].skeleton.n_joints,
            "resample_rate": stream.resample_rate, "frames": stream.frames, "chunk_frames": chunk_frames,
            "chunks": count,
            "characters": [{"id": i, "scale": float(h), "frames": n}
                           for i, h, n in zip(ids, stream.character_scales, frames, strict=True)],
            "skipped": jobs.skipped(job, stream), "warnings": jobs.warned(job, stream)}


async def stream_batch(s: Session, body: dict[str, Any]) -> None:
    """A ``synthesize`` message: start, its chunks (each made in the pool when the window has
    room), end."""
    number = s.begin()
    chunk_frames = _chunk_frames(body, s.settings.ws_chunk_frames)
    job = jobs.parse(body, s.settings, s.state.registry.banks)
    stream = await _open(s, job, chunk_frames)
    count = -(-stream.frames // chunk_frames)
    chunks: Iterator[list[Window]] = stream.chunks()
    req, bank = job.request, s.state.registry.banks[job.request.animal]
    p = encode.packing(req.encoding, req.lod.frame_step, req.lod.detail,
                       [req.characters[c].detail for c in stream.kept], bank.skeleton,
                       stream.character_scales)

    def next_chunk(index: int) -> tuple[int, memoryview]:
        # A chunk's windows (the first's parts) are packed side by side.
        return packed_chunk(number, index, next(chunks), req.encoding, p=p)

    s.started()
    # The first chunk is made while `start` goes out (a client waits for that chunk).
    t0 = time.perf_counter()
    making: asyncio.Future[tuple[int, memoryview]] | None = asyncio.ensure_future(
        s.in_pool(next_chunk, 0)) if count else None
    sent = 0
    try:
        await s.send(_start(s, number, job, stream, chunk_frames, count, p))
        while sent < count:
            if making is None:  # chunks after the first: made when the window has room
                await s.wait_for_room(sent)
                s.check()
                if s.stopped:
                    break
                t0 = time.perf_counter()
                making = asyncio.ensure_future(s.in_pool(next_chunk, sent))
            n, message = await making
            making = None
            s.state.metrics.synthesis_seconds += time.perf_counter() - t0
            s.check()
            if s.stopped:
                break
            await s.send(message)
            s.state.metrics.character_frames += len(stream.kept) * n
            sent += 1
    finally:
        if making is not None:  # leaving early: the chunk under way finishes first (none left running)
            with contextlib.suppress(BaseException):
                await making
    if sent < count:  # stopped early: the client cancelled or left (SIGTERM raised before)
        s.state.metrics.cancelled += 1
    await s.end(number, sent)


async def session(ws: WebSocket, state: State) -> None:
    """One WebSocket connection: its batches and live sessions, in turn."""
    await ws_session.run(ws, state, {"synthesize": stream_batch, "live": live_ws.stream_live})
