"""One WebSocket ``/v1/stream`` connection: the protocol's transport, shared by batches
(:mod:`service.batch_ws`) and live sessions (:mod:`service.live_ws`); docs/streaming.md.

One session, two tasks: a reader that takes every client message as it comes (acks, pings,
cancel, the next batch, a live session's points) and notices a disconnect at once -- even while
the writer is blocked sending -- and the writer, which runs each request's handler: it
synthesizes in the worker pool and sends the chunks, at most ``ws_window`` ahead of the
client's acks. A client that stops reading or acking for ``ws_send_timeout_s`` is closed with
1013; a disconnect stops the work at the next window; SIGTERM closes every session with 1001.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Awaitable, Callable, Mapping, MutableMapping
from typing import Any

import msgpack
from starlette.websockets import WebSocket, WebSocketDisconnect, WebSocketState

from service.errors import ApiError, error_body
from service.state import State

log = logging.getLogger("quadsynth.stream")

GOING_AWAY, INVALID_DATA, POLICY, TOO_BIG, INTERNAL, TRY_LATER = 1001, 1007, 1008, 1009, 1011, 1013
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


def _protocol(code: int, field: str, message: str) -> Closing:
    return Closing(code, ApiError(422, field, message))


Handler = Callable[["Session", dict[str, Any]], Awaitable[None]]


class Session:
    """A connection's state; ``handlers``: the writer's coroutine per request ``type``
    (``synthesize``, ``live``)."""

    def __init__(self, ws: WebSocket, state: State, handlers: Mapping[str, Handler]) -> None:
        self.ws, self.state, self.settings, self.handlers = ws, state, state.settings, handlers
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
            raise _protocol(INVALID_DATA, "message", "send binary msgpack messages, not text")
        try:
            body = msgpack.unpackb(raw, raw=False, strict_map_key=True)
        except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError, TypeError) as exc:
            raise _protocol(INVALID_DATA, "message", f"not valid msgpack: {exc}") from None
        kind = body.get("type") if isinstance(body, dict) else None
        if kind == "ack":
            self.take_ack(body)
        elif kind == "ping":
            asyncio.get_running_loop().create_task(self.pong(body.get("time")))
        elif kind == "cancel":
            self.cancel.set()
        elif kind in ("synthesize", "live"):
            self.take_request(kind, body)
        elif kind in ("points", "finish", "lod", "ground"):
            self.take_points(kind, body, len(raw))
        else:
            raise _protocol(INVALID_DATA, "type", f"unknown message type {kind!r}; expected synthesize, "
                                                  "live, points, lod, ground, finish, ack, ping or cancel")

    def take_ack(self, body: dict[str, Any]) -> None:
        chunk = body.get("chunk")
        if not isinstance(chunk, int) or isinstance(chunk, bool):
            raise _protocol(INVALID_DATA, "chunk", "an ack needs the chunk number (integer)")
        self.acked = max(self.acked, chunk)
        self.ack.set()

    def take_request(self, kind: str, body: dict[str, Any]) -> None:
        if self.requests.qsize() >= 1:  # each may be max_body_bytes: do not hoard them
            raise _protocol(POLICY, "type", "a batch is already waiting behind the one streaming; send "
                                            "the next after its end")
        if kind == "live":
            if self.live_open:
                raise _protocol(POLICY, "type", "a live session is open: finish or cancel it before the next")
            self.live_open = True
        self.requests.put_nowait(body)

    def take_points(self, kind: str, body: dict[str, Any], size: int) -> None:
        if not self.live_open:
            raise _protocol(POLICY, "type", f"{kind} without a live session: send "
                                            "{type: live, characters: [...]} first")
        room = LIVE_INBOX_BODIES * self.settings.max_body_bytes
        if self.inbox.qsize() >= LIVE_INBOX or self.inbox_bytes + size > room:
            waiting = f"{self.inbox.qsize()} points messages ({self.inbox_bytes} bytes)"
            why = f"{waiting} wait, at most {LIVE_INBOX} and {room} bytes: sent faster than made"
            raise Closing(TRY_LATER, ApiError(503, "points", why))
        self.live_open = kind != "finish"
        self.inbox_bytes += size
        body["_bytes"] = size
        self.inbox.put_nowait(body)

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

    def drop_inbox(self) -> None:
        """Points sent after a cancel: dropped."""
        while not self.inbox.empty():
            self.inbox_bytes -= self.inbox.get_nowait().pop("_bytes", 0)

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

    @property
    def stopped(self) -> bool:
        """The client left or cancelled."""
        return self.gone.is_set() or self.cancel.is_set()

    def begin(self) -> int:
        """A new batch or live session: its number."""
        self.batches += 1
        return self.batches

    def started(self) -> None:
        """Its first chunk comes next: acks count from there."""
        self.acked = -1
        self.state.metrics.syntheses += 1

    async def end(self, number: int, sent: int) -> None:
        """The batch's ``end`` message (cancel consumed)."""
        cancelled = self.cancel.is_set()
        self.cancel.clear()
        await self.send({"type": "end", "batch": number, "chunks": sent, "cancelled": cancelled})

    # --- the worker pool -----------------------------------------------------------------------

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

    # --- the session ---------------------------------------------------------------------------

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
                    await self.handlers["live" if request.get("type") == "live" else "synthesize"](
                        self, request)
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


async def run(ws: WebSocket, state: State, handlers: Mapping[str, Handler]) -> None:
    """Serve one connection until it closes (refused with 1013 while loading, 1001 draining)."""
    if not state.registry.loaded or state.draining:
        await ws.close(TRY_LATER if not state.draining else GOING_AWAY)
        return
    await ws.accept()
    me = Session(ws, state, handlers)
    state.sessions.add(me)
    state.metrics.ws_sessions = len(state.sessions)
    try:
        await me.serve()
    finally:
        state.sessions.discard(me)
        state.metrics.ws_sessions = len(state.sessions)
        if not state.sessions:
            state.sessions_closed.set()
