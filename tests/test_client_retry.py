"""The Python client sends a request again when its answer was cut short (a replica that died
mid-answer), a bounded number of times, and counts the retries."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Iterator

import httpx
import msgpack
import numpy as np
import pytest

from api_schemas.client import AsyncClient, Client
from api_schemas.wire import blob, encode_rotations

J = 3


def answer() -> bytes:
    q = np.zeros((5, J, 4), np.float32)
    q[..., 3] = 1.0
    rotations = blob(encode_rotations(q, "s48"))
    rotations["encoding"] = "s48"
    return bytes(msgpack.packb({
        "animal": "horse", "skeleton_id": "horse-x", "fps": 60.0, "encoding": "s48", "resample_rate": 1.0,
        "characters": [{"id": "a", "scale": 1.0, "frames": 5, "root": blob(np.zeros((5, 3), np.float32)),
                        "rotations": rotations, "gait": blob(np.zeros(5, np.int8)),
                        "contacts": blob(np.zeros(5, np.uint8))}], "skipped": []}, use_bin_type=True))


class Cut(httpx.SyncByteStream, httpx.AsyncByteStream):
    """The first half of ``body``, then the connection closes."""

    def __init__(self, body: bytes) -> None:
        self.body = body

    def __iter__(self) -> Iterator[bytes]:
        yield self.body[:len(self.body) // 2]
        raise httpx.RemoteProtocolError("peer closed connection without sending complete message body")

    async def __aiter__(self) -> AsyncIterator[bytes]:
        yield self.body[:len(self.body) // 2]
        raise httpx.RemoteProtocolError("peer closed connection without sending complete message body")


def server(cuts: int) -> tuple[httpx.MockTransport, list[bytes]]:
    """A service whose first ``cuts`` answers are cut short; the bodies it was sent."""
    body, seen = answer(), []

    def handle(request: httpx.Request) -> httpx.Response:
        seen.append(request.read())
        headers = {"content-type": "application/vnd.msgpack", "content-length": str(len(body))}
        if len(seen) <= cuts:
            return httpx.Response(200, headers=headers, stream=Cut(body))
        return httpx.Response(200, headers=headers, stream=httpx.ByteStream(body))

    return httpx.MockTransport(handle), seen


POSITIONS = np.zeros((1, 5, 3), np.float32)


@pytest.mark.parametrize("cuts", [1, 2])
def test_an_answer_cut_short_is_asked_for_again_and_counted(cuts: int) -> None:
    transport, seen = server(cuts)
    with Client("http://qs", max_retries=2) as qs:
        qs._http = httpx.Client(base_url="http://qs", transport=transport)
        motion = qs.synthesize(POSITIONS, seed=1)
    assert motion.characters[0].rotations.shape == (5, J, 4)
    assert qs.retries == cuts and len(seen) == cuts + 1
    assert len(set(seen)) == 1  # the same request each time: same body, same seed


def test_retries_are_bounded() -> None:
    transport, seen = server(cuts=10)
    with Client("http://qs", max_retries=2) as qs:
        qs._http = httpx.Client(base_url="http://qs", transport=transport)
        with pytest.raises(httpx.RemoteProtocolError):
            qs.synthesize(POSITIONS)
    assert len(seen) == 3 and qs.retries == 2


def test_the_async_client_retries_too() -> None:
    transport, seen = server(cuts=1)

    async def run() -> int:
        async with AsyncClient("http://qs") as qs:
            qs._http = httpx.AsyncClient(base_url="http://qs", transport=transport)
            await qs.synthesize(POSITIONS)
            return qs.retries

    assert asyncio.run(run()) == 1 and len(seen) == 2
