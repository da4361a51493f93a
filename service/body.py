"""Request bodies in, response bodies out: msgpack or JSON by Content-Type / Accept, size-capped."""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import msgpack
from fastapi import Request
from fastapi.responses import StreamingResponse
from starlette.types import Receive, Scope, Send

from api_schemas.wire import MSGPACK
from service.errors import ApiError

MSGPACK_TYPES = (MSGPACK, "application/x-msgpack", "application/msgpack")
JSON = "application/json"

log = logging.getLogger("quadsynth.service")


def media_type(header: str | None) -> str:
    return (header or "").split(";")[0].strip().lower()


async def read_body(request: Request, limit: int, timeout_s: float) -> bytes:
    """The whole body, refused with 413 as soon as it passes ``limit`` -- by its Content-Length,
    or while reading (a chunked body has none), so an oversized upload is never held whole --
    and with 408 when it has not arrived whole within ``timeout_s`` (a stalled upload holds a
    connection and its part of the body; nginx has its own timeout, a bare replica has this)."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise ApiError(413, "body", f"{declared} bytes is over the limit of {limit} bytes (max_body_bytes)")
    parts, size = [], 0
    try:
        async with asyncio.timeout(timeout_s):
            async for chunk in request.stream():
                size += len(chunk)
                if size > limit:
                    raise ApiError(413, "body", f"more than the limit of {limit} bytes (max_body_bytes)")
                parts.append(chunk)
    except TimeoutError:
        raise ApiError(408, "body", f"not received whole within {timeout_s:g} s (body_timeout_s): "
                                    f"{size} bytes came", headers={"Connection": "close"}) from None
    return b"".join(parts)


def decode(raw: bytes, content_type: str | None) -> Any:
    kind = media_type(content_type)
    if kind in MSGPACK_TYPES:
        try:
            return msgpack.unpackb(raw, raw=False, strict_map_key=True)
        except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError, TypeError) as exc:
            raise ApiError(422, "body", f"not valid msgpack: {type(exc).__name__} {exc}".rstrip()) from None
    if kind == JSON or kind == "":
        try:
            return json.loads(raw)
        except (ValueError, UnicodeDecodeError, RecursionError) as exc:
            raise ApiError(422, "body", f"not valid JSON: {exc}") from None
    raise ApiError(415, "Content-Type", f"{kind!r} is not accepted: send {MSGPACK} "
                                        f"(or {', '.join(MSGPACK_TYPES[1:])}) or {JSON}")


def wants_msgpack(request: Request) -> bool:
    """Accept decides; without a preference, answer in the request's own format."""
    accept = request.headers.get("accept", "").lower()
    if any(t in accept for t in MSGPACK_TYPES):
        return True
    if JSON in accept:
        return False
    return media_type(request.headers.get("content-type")) in MSGPACK_TYPES


SEND_SLICE = 1024 * 1024  # bytes handed to the server per send: what a stalled socket can pin


class PiecesResponse(StreamingResponse):
    """A 200 answer of a known ``length`` (None: sent chunked) piece by piece as ``pieces``
    yields them (``whole()``: they all came -- ``length`` bytes, or the producer's end);
    ``sent(n)`` is told of each piece once it has left (:class:`service.pipe.Pipe`'s room).

    Each piece goes to the server in slices of ``SEND_SLICE`` bytes: the server's ``send``
    waits while the socket is full, and only then, so a client that stops reading pins one slice
    in the transport, not a piece. A slice not taken within ``send_timeout_s`` ends the answer.
    If the pieces stop short of ``length`` (the work failed or passed its deadline after the
    answer started, or the client stalled), the answer is left incomplete: the server closes the
    connection and the client sees a body cut short, never a shorter answer that parses. A
    client that leaves is noticed between slices (a task waits on ``receive`` for the
    disconnect: the server's ``send`` to a closed connection just returns). ``close(complete)``
    runs at the end in every case."""

    def __init__(self, pieces: AsyncIterator[bytes], length: int | None, media_type: str,  # noqa: PLR0913
                 close: Callable[[bool], Awaitable[None]], sent: Callable[[int], None],
                 send_timeout_s: float, whole: Callable[[], bool]) -> None:
        super().__init__(pieces, 200, {} if length is None else {"content-length": str(length)}, media_type)
        self.pieces, self.close = pieces, close
        self.sent, self.send_timeout_s, self.whole = sent, send_timeout_s, whole

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        async def disconnected() -> None:
            while (await receive())["type"] != "http.disconnect":
                pass

        gone = asyncio.ensure_future(disconnected())
        try:
            async with asyncio.timeout(self.send_timeout_s):
                await send({"type": "http.response.start", "status": self.status_code,
                            "headers": self.raw_headers})
            async for piece in self.pieces:
                view = memoryview(piece)
                for start in range(0, len(view), SEND_SLICE):
                    if gone.done():
                        return
                    async with asyncio.timeout(self.send_timeout_s):
                        await send({"type": "http.response.body", "body": view[start:start + SEND_SLICE],
                                    "more_body": True})
                self.sent(len(view))
            if self.whole() and not gone.done():
                await send({"type": "http.response.body", "body": b"", "more_body": False})
        except TimeoutError:
            log.warning("answer cut short: the client took nothing for %g s (send_timeout_s)",
                        self.send_timeout_s)
        finally:
            gone.cancel()
            await self.close(self.whole() and not gone.done())
