"""Python client for the QuadSynth service: numpy arrays in, numpy arrays out (sync and async).

    from api_schemas.client import Client
    with Client("http://127.0.0.1:8000") as qs:
        motion = qs.synthesize(positions, fps=60, animal="horse", seed=1)   # positions (C, F, 3)
        motion.characters[0].rotations   # (frames, joints, 4) float32 xyzw, whatever the encoding
        for chunk in qs.stream(positions, chunk_frames=30):   # over WebSocket, as it is made
            chunk.rotations   # (characters, 30, joints, 4)

Needs httpx (and websockets to stream); the server is not needed to import this module.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import msgpack
import numpy as np
from numpy.typing import ArrayLike, NDArray

from api_schemas.wire import MSGPACK, blob, rotations_of, unblob

log = logging.getLogger("quadsynth.client")


class ServiceError(RuntimeError):
    """The service refused the request: ``status``, ``field`` and ``message`` say why."""

    def __init__(self, status: int, field: str, message: str) -> None:
        super().__init__(f"{status} {field}: {message}" if field else f"{status} {message}")
        self.status, self.field, self.message = status, field, message


@dataclass(frozen=True)
class CharacterMotion:
    id: str
    scale: float
    root: NDArray[np.float32]  # (F, 3) metres
    rotations: NDArray[np.float32]  # (F, J, 4) local, xyzw
    gait: NDArray[np.int8]  # (F,)
    contacts: NDArray[np.bool_]  # (F, 4) LF, RF, LH, RH


@dataclass(frozen=True)
class Motion:
    animal: str
    skeleton_id: str
    fps: float
    resample_rate: float
    characters: list[CharacterMotion]
    skipped: list[dict[str, Any]] = field(default_factory=list)
    warnings: list[dict[str, Any]] = field(default_factory=list)  # made, but could not keep their path


@dataclass(frozen=True)
class Chunk:
    """Frames ``[start, start + n)`` of every character of a streamed batch (``header``: its
    ``start`` message: ids, scales, each character's own frame count, fps, ...)."""

    header: dict[str, Any]
    index: int
    start: int
    root: NDArray[np.float32]  # (C, n, 3)
    rotations: NDArray[np.float32]  # (C, n, J, 4) xyzw, whatever the encoding (LOD: identity where not sent)
    gait: NDArray[np.int8]  # (C, n)
    contacts: NDArray[np.bool_]  # (C, n, 4)


def decode_chunk(header: dict[str, Any], message: dict[str, Any]) -> Chunk:
    rot = message["rotations"]
    bits = unblob(**message["contacts"])
    return Chunk(header, message["chunk"], message["start"], unblob(**message["root"]),
                 rotations_of(rot, header.get("joints"), len(header.get("characters", [])) or None),
                 unblob(**message["gait"]), (bits[..., None] >> np.arange(4)) & 1 == 1)


def ground(heights: ArrayLike, origin: tuple[float, float] = (0.0, 0.0),
           spacing: float = 1.0) -> dict[str, Any]:
    """A request's ``ground`` (docs/terrain.md): ``heights (rows along z, columns along x)``, the
    (x, z) of ``heights[0, 0]`` and the metres between grid points. Pass it as
    ``client.synthesize(positions, ground=ground(h, (x0, z0), 0.5))``."""
    return {"heights": blob(np.ascontiguousarray(heights, np.float32)),
            "origin": [float(origin[0]), float(origin[1])], "spacing": float(spacing)}


def request_body(positions: ArrayLike, ids: Sequence[str] | None = None,
                 scales: Sequence[float | None] | None = None,
                 details: Sequence[str | None] | None = None, **options: Any) -> bytes:
    """The msgpack body for ``positions``: an array (C, F, 3) or a list of (F_c, 3) arrays
    (``options`` may carry ``type`` and ``chunk_frames`` too: a WebSocket ``synthesize``);
    ``details``: each character's level of detail (None: the request's ``lod``)."""
    paths = [np.asarray(p, np.float32) for p in positions]  # type: ignore[union-attr]
    ids = list(ids) if ids is not None else [str(c) for c in range(len(paths))]
    characters = []
    for c, path in enumerate(paths):
        entry: dict[str, Any] = {"id": ids[c], "points": blob(path)}
        if scales is not None and scales[c] is not None:
            entry["scale"] = float(scales[c])  # type: ignore[arg-type]
        if details is not None and details[c] is not None:
            entry["detail"] = details[c]
        characters.append(entry)
    return bytes(msgpack.packb({**options, "characters": characters}, use_bin_type=True))


def decode_response(content: bytes | bytearray) -> Motion:
    body = msgpack.unpackb(content)
    characters = []
    for ch in body["characters"]:
        rot = ch["rotations"]
        bits = unblob(**ch["contacts"])
        characters.append(CharacterMotion(
            id=ch["id"], scale=ch["scale"], root=unblob(**ch["root"]),
            rotations=rotations_of(rot, body.get("joints")),
            gait=unblob(**ch["gait"]), contacts=(bits[:, None] >> np.arange(4)) & 1 == 1))
    return Motion(body["animal"], body["skeleton_id"], body["fps"], body["resample_rate"], characters,
                  body.get("skipped", []), body.get("warnings", []))


class _Body:
    """A 200 answer's body read into one buffer of its Content-Length as the pieces arrive.

    httpx's ``read()`` keeps every 64 KiB piece and then joins them: twice the answer in fresh
    memory, whose first touch is dear (a quarter of a 64 MB answer's end-to-end time on a VM,
    measured: 0.37 -> 0.28 s for 500 characters x 500 frames)."""

    def __init__(self, headers: Any) -> None:
        self.buffer = bytearray(int(headers["content-length"]))
        self.view = memoryview(self.buffer)
        self.size = 0

    @staticmethod
    def applies(status: int, headers: Any) -> bool:
        length = headers.get("content-length", "")
        return status == 200 and length.isdigit() and "content-encoding" not in headers

    def add(self, piece: bytes) -> None:
        end = self.size + len(piece)
        if end > len(self.buffer):  # h11 refuses this first; a guard all the same
            raise ServiceError(200, "", f"answer longer than its Content-Length ({len(self.buffer)})")
        self.view[self.size:end] = piece
        self.size = end


    def whole(self) -> bytearray:
        if self.size < len(self.buffer):  # httpx says so first; a guard all the same
            raise CutShort(f"answer cut short: {self.size} of {len(self.buffer)} bytes")
        return self.buffer


class CutShort(RuntimeError):
    """An answer that ended before its Content-Length (its connection closed): worth retrying."""


def read_body(response: Any) -> bytes | bytearray:
    """The body of a streamed httpx ``response`` (see :class:`_Body`)."""
    if not _Body.applies(response.status_code, response.headers):
        return bytes(response.read())
    body = _Body(response.headers)
    for piece in response.iter_raw():
        body.add(piece)
    return body.whole()


async def aread_body(response: Any) -> bytes | bytearray:
    """:func:`read_body` of an httpx ``AsyncClient`` stream."""
    if not _Body.applies(response.status_code, response.headers):
        return bytes(await response.aread())
    body = _Body(response.headers)
    async for piece in response.aiter_raw():
        body.add(piece)
    return body.whole()


def _retriable() -> tuple[type[BaseException], ...]:
    """Failures after which the same request may simply be sent again: the connection failed or
    closed before the answer was whole (a replica that died mid-answer). Synthesis is
    idempotent -- the same body and seed give the same bytes -- so a retry is safe."""
    import httpx

    return (httpx.TransportError, CutShort)


def _note_retry(client: Client | AsyncClient, attempt: int, exc: BaseException) -> None:
    client.retries += 1
    log.warning("synthesize: attempt %d of %d failed (%s: %s); retrying", attempt + 1,
                client.max_retries + 1, type(exc).__name__, exc)


def _raise_for(status: int, content: bytes | bytearray) -> None:
    if status == 200:
        return
    try:
        error = json.loads(content)["error"]
        raise ServiceError(status, error.get("field", ""), error.get("message", ""))
    except (ValueError, KeyError, TypeError):
        raise ServiceError(status, "", content[:200].decode("utf-8", "replace")) from None


class Client:
    """Synchronous client; ``timeout`` in seconds (synthesis of big batches takes a while).
    ``max_retries``: how many times :meth:`synthesize` sends a request again whose answer was
    cut short or whose connection failed; ``retries`` counts the retries made."""

    def __init__(self, url: str, timeout: float = 120.0, max_retries: int = 2) -> None:
        import httpx

        self._http = httpx.Client(base_url=url.rstrip("/"), timeout=timeout)
        self.max_retries, self.retries = max_retries, 0

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._http.close()

    def library(self, animal: str) -> dict[str, Any]:
        response = self._http.get(f"/v1/libraries/{animal}")
        _raise_for(response.status_code, response.content)
        return dict(response.json())

    def mesh(self, animal: str) -> bytes:
        """The animal's skinned mesh, a glTF binary (.glb) bound to its skeleton's rest pose."""
        response = self._http.get(f"/v1/libraries/{animal}/mesh.glb")
        _raise_for(response.status_code, response.content)
        return bytes(response.content)

    def limits(self) -> dict[str, Any]:
        response = self._http.get("/v1/limits")
        _raise_for(response.status_code, response.content)
        return dict(response.json())

    def synthesize(self, positions: ArrayLike, ids: Sequence[str] | None = None,
                   scales: Sequence[float | None] | None = None, **options: Any) -> Motion:
        """``options``: the request's fields (animal, fps, seed, sigma, encoding, skip_invalid, ...)."""
        raw = request_body(positions, ids, scales, **options)
        for attempt in range(self.max_retries + 1):
            try:
                with self._http.stream("POST", "/v1/synthesize", content=raw,
                                       headers={"content-type": MSGPACK, "accept": MSGPACK}) as response:
                    content = read_body(response)
                break
            except _retriable() as exc:
                if attempt == self.max_retries:
                    raise
                _note_retry(self, attempt, exc)
        _raise_for(response.status_code, content)
        return decode_response(content)


    def stream(self, positions: ArrayLike, ids: Sequence[str] | None = None,
               scales: Sequence[float | None] | None = None, chunk_frames: int = 30,
               **options: Any) -> Iterator[Chunk]:
        """The batch over WebSocket ``/v1/stream`` (docs/streaming.md), chunk by chunk as the
        server makes them; each chunk is acknowledged once yielded. Needs ``websockets``."""
        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        url = str(self._http.base_url).rstrip("/").replace("http", "ws", 1) + "/v1/stream"
        body = request_body(positions, ids, scales, type="synthesize", chunk_frames=chunk_frames, **options)
        with connect(url, compression=None, max_size=None) as ws:
            ws.send(body)
            header: dict[str, Any] = {}
            while True:
                try:
                    message = msgpack.unpackb(ws.recv())
                except ConnectionClosed as exc:
                    raise ServiceError(exc.rcvd.code if exc.rcvd else 1006, "", "the stream closed") from None
                kind = message["type"]
                if kind == "error":
                    error = message["error"]
                    raise ServiceError(error["status"], error["field"], error["message"])
                if kind == "start":
                    header = message
                elif kind == "chunk":
                    yield decode_chunk(header, message)
                    ws.send(msgpack.packb({"type": "ack", "chunk": message["chunk"]}))
                elif kind == "end":
                    return


    @contextmanager
    def live(self, ids: Sequence[str], fps: float = 60.0, scales: Sequence[float | None] | None = None,
             **options: Any) -> Iterator[LiveSession]:
        """Open a live session for characters ``ids`` whose points come at ``fps``; ``options``:
        animal, seed, sigma, encoding, lod, foot_lock, heading, scale_min, scale_max; ``details``:
        each character's level of detail (None: the session's ``lod``)."""
        from websockets.sync.client import connect

        url = str(self._http.base_url).rstrip("/").replace("http", "ws", 1) + "/v1/stream"
        characters: list[dict[str, Any]] = [{"id": i} for i in ids]
        details = options.pop("details", None) or [None] * len(ids)
        for entry, scale, detail in zip(characters, scales or [None] * len(ids), details, strict=True):
            if scale is not None:
                entry["scale"] = float(scale)
            if detail is not None:
                entry["detail"] = detail
        with connect(url, compression=None, max_size=None) as ws:
            ws.send(msgpack.packb({"type": "live", "fps": fps, **options, "characters": characters},
                                  use_bin_type=True))
            session = LiveSession(ws, {})
            message = msgpack.unpackb(ws.recv())
            session._take(message, [])
            session.header = message
            yield session


class LiveSession:
    """A live session over WebSocket ``/v1/stream`` (docs/streaming.md): :meth:`push` every
    character's next points as the simulation runs, get back the chunks ready so far;
    :meth:`finish` when the trajectories end. ``header``: the session's ``start`` message (ids,
    scales, output fps, ``latency_frames``)."""

    def __init__(self, ws: Any, header: dict[str, Any]) -> None:
        self.ws, self.header = ws, header
        self.ended = False

    def _take(self, message: dict[str, Any], out: list[Chunk]) -> None:
        kind = message["type"]
        if kind == "error":
            error = message["error"]
            raise ServiceError(error["status"], error["field"], error["message"])
        if kind == "chunk":
            out.append(decode_chunk(self.header, message))
            self.ws.send(msgpack.packb({"type": "ack", "chunk": message["chunk"]}))
        elif kind == "end":
            self.ended = True

    def _receive(self, timeout: float | None) -> list[Chunk]:
        from websockets.exceptions import ConnectionClosed

        out: list[Chunk] = []
        while not self.ended:
            try:
                raw = self.ws.recv(timeout=timeout)
            except TimeoutError:
                break
            except ConnectionClosed as exc:
                raise ServiceError(exc.rcvd.code if exc.rcvd else 1006, "", "the session closed") from None
            self._take(msgpack.unpackb(raw), out)
        return out

    def push(self, points: ArrayLike, wait: float = 0.0, velocity: ArrayLike | None = None) -> list[Chunk]:
        """Send ``points (characters, n, 3)`` (and, if the simulation knows it, each point's
        ``velocity (characters, n, 2)``: x and z, m/s, which the low-latency mode reads for speed
        and heading); the chunks that arrived meanwhile (waiting up to ``wait`` seconds for the
        first)."""
        message: dict[str, Any] = {"type": "points", "points": blob(np.ascontiguousarray(points, np.float32))}
        if velocity is not None:
            message["velocity"] = blob(np.ascontiguousarray(velocity, np.float32))
        self.ws.send(msgpack.packb(message, use_bin_type=True))
        out = self._receive(wait) if wait > 0 else []
        return out + self._receive(0)

    def set_ground(self, ground: dict[str, Any] | None, wait: float = 0.0) -> list[Chunk]:
        """The terrain from the next frames rendered on (:func:`ground` makes one; None: the
        points' y again); the chunks that arrived meanwhile, as :meth:`push`."""
        self.ws.send(msgpack.packb({"type": "ground", "ground": ground}, use_bin_type=True))
        out = self._receive(wait) if wait > 0 else []
        return out + self._receive(0)

    def finish(self) -> list[Chunk]:
        """The trajectories end here: every chunk still to come, up to the session's end."""
        self.ws.send(msgpack.packb({"type": "finish"}))
        return self._receive(None)


class AsyncClient:
    """The same, for asyncio."""

    def __init__(self, url: str, timeout: float = 120.0, max_retries: int = 2) -> None:
        import httpx

        self._http = httpx.AsyncClient(base_url=url.rstrip("/"), timeout=timeout)
        self.max_retries, self.retries = max_retries, 0

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self._http.aclose()

    async def synthesize(self, positions: ArrayLike, ids: Sequence[str] | None = None,
                         scales: Sequence[float | None] | None = None, **options: Any) -> Motion:
        raw = request_body(positions, ids, scales, **options)
        for attempt in range(self.max_retries + 1):
            try:
                async with self._http.stream("POST", "/v1/synthesize", content=raw, headers={
                        "content-type": MSGPACK, "accept": MSGPACK}) as response:
                    content = await aread_body(response)
                break
            except _retriable() as exc:
                if attempt == self.max_retries:
                    raise
                _note_retry(self, attempt, exc)
        _raise_for(response.status_code, content)
        return decode_response(content)
