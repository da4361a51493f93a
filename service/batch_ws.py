"""WebSocket ``/v1/stream``: a batch's motion in chunks of K frames, each sent as soon as it is
made; or a live session, its frames sent as the points that settle them arrive
(docs/streaming.md has the protocol).

One session, two tasks: a reader that takes every client message as it comes (acks, pings,
cancel, the next batch) and notices a disconnect at once -- even while the writer is blocked
sending -- and the writer, which synthesizes window after window in the worker pool and sends
the chunks, at most ``ws_window`` ahead of the client's acks. A client that stops reading or
acking for ``ws_send_timeout_s`` is closed with 1013; a disconnect stops the work at the next
window; SIGTERM closes every session with 1001.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import time
from collections.abc import Awaitable, Callable, Iterator, MutableMapping
from typing import TYPE_CHECKING, Any

import msgpack
from starlette.websockets import WebSocket, WebSocketDisconnect, WebSocketState

from service import encode, jobs
from service import live_ws as live
from service.chunk import packed_chunk
from service.errors import ApiError, error_body
from service.packing import skeleton_id
from synth_core.runtime.streaming import BatchStream, Window
from synth_core.runtime.trajectory import TrajectoryError

if TYPE_CHECKING:
    from service.app import State

log = logging.getLogger("quadsynth.stream")

GOING_AWAY, INVALID_DATA, POLICY, TOO_BIG, INTERNAL, TRY_LATER = 1001, 1007, 1008, 1009, 1011, 1013
MAX_CHUNK_FRAMES = 600
LIVE_INBOX = 64  # points messages waiting for synthesis, at most: a client further ahead gets 1013
LIVE_INBOX_BODIES = 4  # ... and at most this many max_body_bytes of them
CLOSE_TIMEOUT_S = 1.0
# HTTP status of an error -> the close code after it.
CLOSE_FOR = {404: INVALID_DATA, 413: TOO_BIG, 415: INVALID_DATA, 422: INVALID_DATA,
             503: TRY_LATER, 504: TRY_LATER}


def give_back(taking: asyncio.Future[Callable[[], None]]) -> None:
    """A slot being taken that is not wanted any more: the taking cancelled, or the slot given
    back should it be (or have been) taken after all."""
    def done(future: asyncio.Future[Callable[[], None]]) -> None:
        if not future.cancelled() and future.exception() is None:
            future.result()()

    if taking.done():
        done(taking)
    else:
        taking.cancel()
        taking.add_done_callback(done)


class Closing(Exception):
    """End the session: send ``error`` (if any), then close with ``code``."""

    def __init__(self, code: int, error: ApiError | None = None) -> None:
        super().__init__(code)
        self.code, self.error = code, error


def pack(message: dict[str, Any]) -> bytes:
    return msgpack.packb(message, use_bin_type=True)  # type: ignore[no-any-return]


class Session:
    def __init__(self, ws: WebSocket, state: State) -> None:
        self.ws, self.state, self.settings = ws, state, state.settings
        self.requests: asyncio.Queue[dict[str, Any]] = asyncio.Queue()
        self.acked = -1  # the last chunk acknowledged (acks are cumulative)
        self.ack = asyncio.Event()
        self.cancel = asyncio.Event()
        self.gone = asyncio.Event()  # the client disconnected
        self.reader_done = asyncio.Event()  # the reader stopped: the client left or broke the protocol
        self.failure: Closing | None = None  # a protocol error the reader found
        self.send_lock = asyncio.Lock()
        self.batches = 0
        self.inbox: asyncio.Queue[dict[str, Any]] = asyncio.Queue()  # a live session's points, finish
        self.live_open = False  # a live session was asked for and has not finished
        self.inbox_bytes = 0

    # --- reading -------------------------------------------------------------------------------

    async def read(self) -> None:
        """Every client message, as it arrives, until the client goes."""
        try:
            while True:
                message = await self.ws.receive()
                if message["type"] == "websocket.disconnect":
                    return
                self.take(message)
        except (WebSocketDisconnect, RuntimeError):
            return
        except Closing as exc:
            self.failure = exc
        finally:
            if self.failure is None:
                self.gone.set()
            self.ack.set()  # wake a writer waiting for acks
            self.reader_done.set()  # ... or for a live session's points

    def take(self, message: MutableMapping[str, Any]) -> None:
        raw = message.get("bytes")
        if raw is None:
            raise Closing(INVALID_DATA, ApiError(422, "message", "send binary msgpack messages, not text"))
        try:
            body = msgpack.unpackb(raw, raw=False, strict_map_key=True)
        except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError, TypeError) as exc:
            raise Closing(INVALID_DATA, ApiError(422, "message", f"not valid msgpack: {exc}")) from None
        kind = body.get("type") if isinstance(body, dict) else None
        if kind == "ack":
            chunk = body.get("chunk")
            if not isinstance(chunk, int) or isinstance(chunk, bool):
                raise Closing(INVALID_DATA, ApiError(422, "chunk", "an ack needs the chunk number (integer)"))
            self.acked = max(self.acked, chunk)
            self.ack.set()
        elif kind == "ping":
            asyncio.get_running_loop().create_task(self.pong(body.get("time")))
        elif kind == "cancel":
            self.cancel.set()
        elif kind in ("synthesize", "live"):
            if self.requests.qsize() >= 1:  # each may be max_body_bytes: do not hoard them
                raise Closing(POLICY, ApiError(422, "type", "a batch is already waiting behind the one "
                                                            "streaming; send the next after its end"))
            if kind == "live":
                if self.live_open:
                    raise Closing(POLICY, ApiError(422, "type", "a live session is open: finish or "
                                                                "cancel it before the next"))
                self.live_open = True
            self.requests.put_nowait(body)
        elif kind in ("points", "finish", "lod"):
            if not self.live_open:
                raise Closing(POLICY, ApiError(422, "type", f"{kind} without a live session: send "
                                                            "{type: live, characters: [...]} first"))
            room = LIVE_INBOX_BODIES * self.settings.max_body_bytes
            if self.inbox.qsize() >= LIVE_INBOX or self.inbox_bytes + len(raw) > room:
                waiting = f"{self.inbox.qsize()} points messages ({self.inbox_bytes} bytes)"
                why = f"{waiting} wait, at most {LIVE_INBOX} and {room} bytes: sent faster than made"
                raise Closing(TRY_LATER, ApiError(503, "points", why))
            self.live_open = kind != "finish"
            self.inbox_bytes += len(raw)
            body["_bytes"] = len(raw)
            self.inbox.put_nowait(body)
        else:
            raise Closing(INVALID_DATA, ApiError(422, "type", f"unknown message type {kind!r}; expected "
                                                              "synthesize, live, points, lod, finish, ack, "
                                                              "ping or cancel"))

    # --- writing -------------------------------------------------------------------------------

    async def send(self, message: dict[str, Any] | bytes | memoryview) -> None:
        """Send (a message, or one packed already), unless the client is gone; a client that
        does not take it in time: 1013."""
        if self.gone.is_set():
            return
        limit = self.settings.ws_send_timeout_s
        raw = pack(message) if isinstance(message, dict) else message
        async with self.send_lock:
            try:
                # A packed chunk is a memoryview of its buffer (30 MB for a live tick of 4,000 horses:
                # a copy into bytes cost two-thirds as much as packing it). ASGI says bytes; uvicorn's
                # websockets-sansio protocol, which `quadsynth serve` runs, sends any bytes-like object.
                await asyncio.wait_for(self.ws.send_bytes(raw), limit)  # type: ignore[arg-type]
            except TimeoutError:
                raise Closing(TRY_LATER, ApiError(503, "", f"slow consumer: a message was not taken within "
                                                           f"{limit:g} s (ws_send_timeout_s)")) from None
            except (WebSocketDisconnect, RuntimeError, OSError):
                self.gone.set()

    async def pong(self, stamp: Any) -> None:
        try:
            await self.send({"type": "pong", "time": stamp})
        except Closing as exc:
            self.failure = exc
            self.ack.set()

    async def wait_for_room(self, index: int) -> None:
        """Hold chunk ``index`` until fewer than ``ws_window`` chunks are unacknowledged."""
        window, limit = self.settings.ws_window, self.settings.ws_send_timeout_s
        deadline = time.monotonic() + limit
        while index - self.acked > window and not (self.gone.is_set() or self.cancel.is_set()):
            self.check()
            self.ack.clear()
            left = deadline - time.monotonic()
            if left <= 0:
                raise Closing(TRY_LATER, ApiError(503, "", f"slow consumer: {window} chunks unacknowledged "
                                                           f"for {limit:g} s (ws_window, ws_send_timeout_s)"))
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.ack.wait(), left)

    def check(self) -> None:
        if self.failure is not None:
            raise self.failure
        if self.state.draining:
            raise Closing(GOING_AWAY, ApiError(503, "", "the server is shutting down; reconnect to "
                                                        "another replica"))

    async def pool_slot(self, take: Callable[[], Awaitable[Callable[[], None]]]) -> Callable[[], None]:
        """A slot of the worker pool (``take``: the admission's ``admit`` or ``wait_turn``) -- or,
        if SIGTERM comes first, the session closes with 1001 and an error saying so (uvicorn's
        own shutdown would close a session still waiting with 1012)."""
        taking = asyncio.ensure_future(take())
        drain = asyncio.ensure_future(self.state.drain.wait())
        try:
            await asyncio.wait({taking, drain}, return_when=asyncio.FIRST_COMPLETED)
            self.check()  # draining: 1001
        except BaseException:  # that, or this coroutine cancelled: the slot is not taken
            give_back(taking)
            raise
        finally:
            drain.cancel()
        return taking.result()

    async def in_pool(self, fn: Any, *args: Any) -> Any:
        """``fn(*args)`` in the worker pool, in turn with REST syntheses."""
        loop = asyncio.get_running_loop()
        release = await self.pool_slot(self.state.admission.wait_turn)
        try:
            return await loop.run_in_executor(self.state.pool, fn, *args)
        finally:
            release()

    async def batch(self, body: dict[str, Any]) -> None:
        settings, registry = self.settings, self.state.registry
        self.batches += 1
        number = self.batches
        chunk_frames = body.pop("chunk_frames", settings.ws_chunk_frames)
        body.pop("type", None)
        if (not isinstance(chunk_frames, int) or isinstance(chunk_frames, bool)
                or not 1 <= chunk_frames <= MAX_CHUNK_FRAMES):
            raise ApiError(422, "chunk_frames", f"must be an integer from 1 to {MAX_CHUNK_FRAMES}, "
                                                f"got {chunk_frames!r}")
        job = jobs.parse(body, settings, registry.banks)
        req = job.request
        bank = registry.banks[req.animal]
        release = await self.pool_slot(self.state.admission.admit)  # refused (503 -> 1013) when full
        try:
            stream: BatchStream = await asyncio.get_running_loop().run_in_executor(
                self.state.pool, jobs.open_stream, job, bank, chunk_frames)
        finally:
            release()
        frames = jobs.output_frames(job, stream.frames, stream.kept)
        ids = [job.ids[c] for c in stream.kept]
        count = -(-stream.frames // chunk_frames)
        chunks: Iterator[list[Window]] = stream.chunks()

        p = encode.packing(req.encoding, req.lod.frame_step, req.lod.detail,
                           [req.characters[c].detail for c in stream.kept], bank.skeleton,
                           stream.character_scales)

        def next_chunk(index: int) -> tuple[int, memoryview]:
            # A chunk's windows (the first's parts) are packed side by side.
            return packed_chunk(number, index, next(chunks), req.encoding, p=p)

        self.acked, sent = -1, 0
        self.state.metrics.syntheses += 1
        # The first chunk is made while `start` goes out (a client waits for that chunk).
        t0 = time.perf_counter()
        making: asyncio.Future[tuple[int, memoryview]] | None = asyncio.ensure_future(
            self.in_pool(next_chunk, 0)) if count else None
        try:
            await self.send({
                "type": "start", "batch": number, "animal": req.animal,
                "skeleton_id": skeleton_id(req.animal, registry.libraries[req.animal].skeleton),
                "fps": bank.fps / p.frame_step, "frame_step": p.frame_step, "encoding": req.encoding,
                "details": list(p.details), "joints": bank.skeleton.n_joints,
                "resample_rate": stream.resample_rate,
                "frames": stream.frames, "chunk_frames": chunk_frames, "chunks": count,
                "characters": [{"id": i, "scale": float(h), "frames": n}
                               for i, h, n in zip(ids, stream.character_scales, frames, strict=True)],
                "skipped": jobs.skipped(job, stream), "warnings": jobs.warned(job, stream)})
            while sent < count:
                if making is None:  # chunks after the first: made when the window has room
                    await self.wait_for_room(sent)
                    self.check()
                    if self.gone.is_set() or self.cancel.is_set():
                        break
                    t0 = time.perf_counter()
                    making = asyncio.ensure_future(self.in_pool(next_chunk, sent))
                n, message = await making
                making = None
                self.state.metrics.synthesis_seconds += time.perf_counter() - t0
                self.check()
                if self.gone.is_set() or self.cancel.is_set():
                    break
                await self.send(message)
                self.state.metrics.character_frames += len(ids) * n
                sent += 1
        finally:
            if making is not None:  # leaving early: the chunk under way finishes first (none left running)
                with contextlib.suppress(BaseException):
                    await making
        cancelled = self.cancel.is_set()
        if sent < count:  # stopped early: the client cancelled or left (SIGTERM raised before)
            self.state.metrics.cancelled += 1
        self.cancel.clear()
        await self.send({"type": "end", "batch": number, "chunks": sent, "cancelled": cancelled})

    async def next_live(self) -> dict[str, Any] | None:
        """The live session's next points (or finish) message; None once the client goes or cancels."""
        events = (self.reader_done, self.cancel, self.state.drain)
        waits = {asyncio.ensure_future(e.wait()) for e in events}
        get = asyncio.ensure_future(self.inbox.get())
        try:
            await asyncio.wait({get, *waits}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for w in waits:
                w.cancel()
        self.check()
        if not get.done():
            get.cancel()
            return None
        message = get.result()
        self.inbox_bytes -= message.pop("_bytes", 0)
        return message

    async def live(self, body: dict[str, Any]) -> None:
        """A live session: frames for the points as they come, until finish."""
        settings, registry = self.settings, self.state.registry
        self.batches += 1
        number = self.batches
        req, synth = live.open_live(body, settings, registry.banks)
        bank = registry.banks[req.animal]
        C = len(req.characters)
        p = encode.packing(req.encoding, req.lod.frame_step, req.lod.detail,
                           [c.detail for c in req.characters], bank.skeleton, synth.scales)
        out_fps = bank.fps / synth.out_step / p.frame_step
        await self.send({
            "type": "start", "batch": number, "mode": "live", "animal": req.animal,
            "skeleton_id": skeleton_id(req.animal, registry.libraries[req.animal].skeleton),
            "fps": out_fps, "library_fps": bank.fps, "frame_step": p.frame_step, "encoding": req.encoding,
            "details": list(p.details), "joints": bank.skeleton.n_joints, "resample_rate": 1.0,
            "latency_frames": -(-synth.latency_frames // synth.out_step),
            "latency_s": synth.latency_frames / bank.fps,
            "characters": [{"id": c.id, "scale": float(h)} for c, h in zip(req.characters, synth.scales,
                                                                          strict=True)]})
        self.acked, sent = -1, 0
        self.state.metrics.syntheses += 1

        # Windows of at most a segment's frames: a finish (or a long points message) settling
        # more comes as several chunks, each window rendered and packed over the last's pages
        # (fresh pages, zeroed by the OS as they are first written, took a fifth of the server's
        # CPU in a live session: perf) -- and over an earlier session's (see Shelf).
        scratch = self.state.scratches.take()
        stepping = False  # a step may be writing into scratch

        W = synth.window_frames

        def step(advance: Callable[[], list[Window] | None], index: int) -> tuple[int, memoryview] | None:
            """The next chunk: of the windows ``advance`` gives (then of those left), None
            when there are none."""
            windows = advance()
            while windows is not None and windows[0].stop <= windows[0].start:  # no frame sent in it
                windows = synth.take(W)
            if windows is None:
                return None
            # Two buffers in turn: one is sent while the next is packed.
            return packed_chunk(number, index, windows, req.encoding, scratch, f"chunk{index % 2}", p)

        # A chunk goes out while the next is synthesized (a live tick of 4,000 horses is ~30 MB:
        # sending it took a third as long as making it, the cores half idle meanwhile).
        sending: asyncio.Future[None] | None = None
        try:
            while True:
                message = await self.next_live()
                if message is None:  # before its finish: the client cancelled or left
                    self.state.metrics.cancelled += 1
                    break
                if message.get("type") == "lod":  # the characters' details from the next chunk on
                    p = live.new_details(p, message)
                    continue
                finishing = message.get("type") == "finish"
                advance = (functools.partial(synth.finish, W) if finishing else
                           functools.partial(synth.append, live.points(message, C, settings), W))
                while True:
                    t0 = time.perf_counter()
                    stepping = True
                    try:
                        made = await self.in_pool(step, advance, sent)
                    except TrajectoryError as exc:
                        stepping = False
                        raise live.live_error(exc, "points") from None
                    stepping = False
                    self.state.metrics.synthesis_seconds += time.perf_counter() - t0
                    if sending is not None:
                        await sending  # in order, and its failure (a slow consumer) raised here
                        sending = None
                    if made is None:
                        break
                    await self.wait_for_room(sent)
                    self.check()
                    sending = asyncio.ensure_future(self.send(made[1]))
                    self.state.metrics.character_frames += C * made[0]
                    sent += 1
                    advance = functools.partial(synth.take, W)
                if finishing:
                    break
            if sending is not None:
                last, sending = sending, None
                await last
        finally:
            if sending is not None:  # leaving on an error: let its send finish first (this error wins)
                with contextlib.suppress(Exception):
                    await sending
            # Back for the next session unless a step or a send may still be using it (this
            # coroutine cancelled while one ran; the pool thread goes on): then left to the GC.
            if not stepping and (sending is None or sending.done()):
                self.state.scratches.give(scratch)
        cancelled = self.cancel.is_set()
        self.cancel.clear()
        self.live_open = False
        while not self.inbox.empty():  # points sent after a cancel
            self.inbox_bytes -= self.inbox.get_nowait().pop("_bytes", 0)
        await self.send({"type": "end", "batch": number, "chunks": sent, "cancelled": cancelled})

    async def serve(self) -> None:
        reader = asyncio.get_running_loop().create_task(self.read())
        drain = asyncio.get_running_loop().create_task(self.state.drain.wait())  # SIGTERM
        try:
            while True:
                nxt = asyncio.get_running_loop().create_task(self.requests.get())
                done, _ = await asyncio.wait({nxt, reader, drain}, return_when=asyncio.FIRST_COMPLETED)
                if nxt not in done:
                    nxt.cancel()
                    self.check()
                    return  # the client went away
                request = nxt.result()
                try:
                    if request.get("type") == "live":
                        await self.live(request)
                    else:
                        await self.batch(request)
                except ApiError as exc:
                    raise Closing(CLOSE_FOR.get(exc.status, POLICY), exc) from None
                if self.gone.is_set():
                    return
        except Closing as exc:
            await self.close(exc)
        except Exception:  # never leave a client hanging: a typed error, then 1011
            log.exception("stream session failed")
            await self.close(Closing(INTERNAL, ApiError(500, "", "internal error; the session is closed")))
        finally:
            reader.cancel()
            drain.cancel()

    async def close(self, exc: Closing) -> None:
        """The typed error, then the close code (each bounded: the client may not be reading)."""
        if self.gone.is_set() or self.ws.client_state != WebSocketState.CONNECTED:
            return
        e = exc.error
        with contextlib.suppress(Exception):
            if e is not None:
                message = pack({"type": "error", **error_body(e.status, e.field, e.message)})
                await asyncio.wait_for(self.ws.send_bytes(message), CLOSE_TIMEOUT_S)
        with contextlib.suppress(Exception):
            # The close reason must fit a control frame (123 bytes); the error message has it all.
            await asyncio.wait_for(self.ws.close(exc.code, e.message[:100] if e else None), CLOSE_TIMEOUT_S)


async def session(ws: WebSocket, state: State) -> None:
    if not state.registry.loaded or state.draining:
        await ws.close(TRY_LATER if not state.draining else GOING_AWAY)
        return
    await ws.accept()
    me = Session(ws, state)
    state.sessions.add(me)
    state.metrics.ws_sessions = len(state.sessions)
    try:
        await me.serve()
    finally:
        state.sessions.discard(me)
        state.metrics.ws_sessions = len(state.sessions)
        if not state.sessions:
            state.sessions_closed.set()
