"""WebSocket /v1/stream from the tests' side: messages sent and read (msgpack), a batch streamed
whole with acks, typed errors with their close codes."""

from __future__ import annotations

from typing import Any

import msgpack
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection


def ws_url(url: str) -> str:
    return url.replace("http://", "ws://") + "/v1/stream"


def send(ws: ClientConnection, message: dict[str, Any]) -> None:
    ws.send(msgpack.packb(message, use_bin_type=True))


def receive(ws: ClientConnection, timeout: float = 30) -> dict[str, Any]:
    return msgpack.unpackb(ws.recv(timeout=timeout))  # type: ignore[no-any-return]


def closed_with(ws: ClientConnection, code: int, status: int, field: str, *words: str) -> None:
    """The next message is a typed error, then the connection closes with ``code``."""
    error = receive(ws)
    assert error["type"] == "error", error
    assert error["error"]["status"] == status and error["error"]["field"] == field, error
    for word in words:
        assert word in error["error"]["message"], error
    with pytest.raises(ConnectionClosed) as closed:
        ws.recv(timeout=10)
    assert closed.value.rcvd is not None and closed.value.rcvd.code == code


def stream_all(ws: ClientConnection, body: dict[str, Any]) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    send(ws, {"type": "synthesize", **body})
    head = receive(ws)
    assert head["type"] == "start", head
    chunks = []
    while (m := receive(ws))["type"] == "chunk":
        chunks.append(m)
        send(ws, {"type": "ack", "chunk": m["chunk"]})
    assert m == {"type": "end", "batch": head["batch"], "chunks": len(chunks), "cancelled": False}
    return head, chunks
