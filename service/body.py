"""Request bodies in, response bodies out: msgpack or JSON by Content-Type / Accept, size-capped."""

from __future__ import annotations

import asyncio
import base64
import json
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import msgpack
from fastapi import Request
from fastapi.responses import Response, StreamingResponse
from starlette.types import Receive, Scope, Send

from api_schemas.wire import MSGPACK
from service.errors import ApiError

MSGPACK_TYPES = (MSGPACK, "application/x-msgpack", "application/msgpack")
JSON = "application/json"


def media_type(header: str | None) -> str:
    return (header or "").split(";")[0].strip().lower()


async def read_body(request: Request, limit: int) -> bytes:
    """The whole body, refused with 413 as soon as it passes ``limit`` -- by its Content-Length,
    or while reading (a chunked body has none), so an oversized upload is never held whole."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise ApiError(413, "body", f"{declared} bytes is over the limit of {limit} bytes (max_body_bytes)")
    parts, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise ApiError(413, "body", f"more than the limit of {limit} bytes (max_body_bytes)")
        parts.append(chunk)
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


def _base64_bytes(value: Any) -> Any:
    if isinstance(value, bytes):
        return base64.b64encode(value).decode("ascii")
    if isinstance(value, dict):
        return {k: _base64_bytes(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_base64_bytes(v) for v in value]
    return value


def encode(body: Any, as_msgpack: bool, status: int = 200) -> Response:
    if as_msgpack:
        return Response(msgpack.packb(body, use_bin_type=True), status, media_type=MSGPACK)
    return Response(json.dumps(_base64_bytes(body), separators=(",", ":")), status, media_type=JSON)


class PiecesResponse(StreamingResponse):
    """A 200 answer of a known ``length`` sent piece by piece as ``pieces`` yields them.

    If the pieces stop short of ``length`` (the work failed or passed its deadline after the
    answer started), the answer is left incomplete: the server closes the connection and the
    client sees a body cut short, never a shorter answer that parses. A client that leaves is
    noticed between pieces (a task waits on ``receive`` for the disconnect: the server's
    ``send`` to a closed connection just returns). ``close`` runs at the end in every case."""

    def __init__(self, pieces: AsyncIterator[bytes], length: int, media_type: str,
                 close: Callable[[], Awaitable[None]]) -> None:
        super().__init__(pieces, 200, {"content-length": str(length)}, media_type)
        self.length, self.close = length, close

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        async def disconnected() -> None:
            while (await receive())["type"] != "http.disconnect":
                pass

        gone = asyncio.ensure_future(disconnected())
        sent = 0
        try:
            await send({"type": "http.response.start", "status": self.status_code,
                        "headers": self.raw_headers})
            async for piece in self.body_iterator:
                if gone.done():
                    break
                await send({"type": "http.response.body", "body": piece, "more_body": True})
                sent += len(piece)
            if sent == self.length and not gone.done():
                await send({"type": "http.response.body", "body": b"", "more_body": False})
        finally:
            gone.cancel()
            await self.close()
