"""The service benchmark's WebSocket client: RFC 6455 framing over a plain socket, every
message received straight into one reused buffer and only its head decoded.

On this two-core machine the client shares the cores it measures. A live session of 4,000
horses sends ~30 MB a chunk; the websockets library receives a message through three copies
(socket pieces, its stream buffer, the message) and msgpack decodes every blob into a fourth --
half a core-second a session taken from the service. A game client (C++, C#) reads a chunk
into its own buffer and decodes the rotations in place; this does the reading that way and
skips the decoding (the benchmark needs a chunk's number and frame count only). Not a general
client: no fragmented messages, no extensions -- what ``quadsynth serve`` sends.
"""

from __future__ import annotations

import base64
import os
import select
import socket
import struct
from typing import Any
from urllib.parse import urlsplit

import msgpack
import numpy as np

_BINARY, _CLOSE, _PING, _PONG = 0x2, 0x8, 0x9, 0xA
HEAD_BYTES = 512  # a chunk's fields before its first blob (type, batch, chunk, start, frames)


class LeanSocket:
    """A client WebSocket: :meth:`send` binary messages, :meth:`recv_head` the next message's
    leading fields (pings answered on the way)."""

    def __init__(self, url: str, timeout: float = 300.0) -> None:
        parts = urlsplit(url)
        self.sock = socket.create_connection((parts.hostname, parts.port or 80), timeout=timeout)
        self.last_bytes = 0  # the size of the last message recv_head read
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET {parts.path or '/'} HTTP/1.1\r\nHost: {parts.netloc}\r\n"
                           "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                           f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
        reply = b""
        while b"\r\n\r\n" not in reply:
            piece = self.sock.recv(4096)
            if not piece:
                raise ConnectionError("the server closed the connection during the handshake")
            reply += piece
        head, self.pending = reply.split(b"\r\n\r\n", 1)
        if not head.startswith(b"HTTP/1.1 101"):
            raise ConnectionError(f"no WebSocket upgrade: {head.splitlines()[0]!r}")
        self.buffer = bytearray(1 << 20)

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> LeanSocket:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def send(self, payload: bytes, opcode: int = _BINARY) -> None:
        n = len(payload)
        head = bytes([0x80 | opcode])
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 1 << 16:
            head += struct.pack(">BH", 0x80 | 126, n)
        else:
            head += struct.pack(">BQ", 0x80 | 127, n)
        mask = os.urandom(4)
        words = np.zeros(-(-n // 4), np.uint32)  # masked four bytes at a time
        words.view(np.uint8)[:n] = np.frombuffer(payload, np.uint8)
        words ^= np.frombuffer(mask, np.uint32)[0]
        self.sock.sendall(head + mask + words.view(np.uint8)[:n].tobytes())

    def _read_into(self, view: memoryview) -> None:
        got = 0
        if self.pending:
            got = min(len(self.pending), len(view))
            view[:got] = self.pending[:got]
            self.pending = self.pending[got:]
        while got < len(view):
            n = self.sock.recv_into(view[got:])
            if n == 0:
                raise ConnectionError("the server closed the connection")
            got += n

    def recv_head(self, timeout: float | None = None) -> dict[str, Any]:
        """The next binary message's leading fields (its blobs are read, not decoded);
        TimeoutError if none starts within ``timeout`` seconds."""
        if timeout is not None and not self.pending and not select.select([self.sock], [], [], timeout)[0]:
            raise TimeoutError
        while True:
            head = memoryview(bytearray(2))
            self._read_into(head)
            opcode, n = head[0] & 0x0F, head[1] & 0x7F
            if n >= 126:
                ext = memoryview(bytearray(2 if n == 126 else 8))
                self._read_into(ext)
                n = int.from_bytes(ext, "big")
            if n > len(self.buffer):
                self.buffer = bytearray(n)
            body = memoryview(self.buffer)[:n]
            self._read_into(body)
            if opcode == _PING:
                self.send(bytes(body), _PONG)
            elif opcode == _CLOSE:
                code = int.from_bytes(body[:2], "big") if n >= 2 else 1005
                raise ConnectionError(f"the server closed the session: {code} {bytes(body[2:])!r}")
            elif opcode == _BINARY:
                self.last_bytes = n  # the message's size on the wire
                return _leading_fields(body)


def _leading_fields(message: memoryview) -> dict[str, Any]:
    """A chunk message's fields before its blobs; any other message whole."""
    unpacker = msgpack.Unpacker()
    unpacker.feed(message[:HEAD_BYTES])
    try:
        fields: dict[str, Any] = {}
        for _ in range(unpacker.read_map_header()):
            key = unpacker.unpack()
            if key == "root":  # a chunk's first blob: its head is read
                return fields
            fields[key] = unpacker.unpack()
    except msgpack.OutOfData:
        pass
    return msgpack.unpackb(message)  # type: ignore[no-any-return]
