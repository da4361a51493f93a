"""deploy/nginx.conf for real: nginx (installed from Debian by scripts/ensure-nginx if missing) in
front of two `quadsynth serve` processes on loopback. Requests, a WebSocket stream and a live
session pass through and spread over both; a replica that answers 503 or is gone is retried on the other;
an oversized body is refused by nginx in the service's error format.

The config is the deployed file with only what Docker provides rewritten: the two replicas'
addresses instead of the service name (Debian's nginx 1.22 has no `resolve`), and the port,
pid and temporary paths.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator

import httpx
import msgpack
import numpy as np
import pytest

from api_schemas.client import Client
from api_schemas.wire import blob
from synth_core.quality import herd_sim as crowd
from tests.helpers.nginx import QUEUED, Cluster, nginx_cluster
from tests.helpers.servers import in_flight

MSGPACK = "application/vnd.msgpack"
@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    """(nginx URL, the two replicas' own URLs, their processes, nginx's error log)."""
    with nginx_cluster(tmp_path_factory) as running:
        yield running


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(3, 120, seed=2).astype(np.float32)


def body(herd: np.ndarray) -> bytes:
    return bytes(msgpack.packb({"animal": "horse", "seed": 1, "characters": [
        {"id": f"h{c}", "points": blob(herd[c])} for c in range(len(herd))]}, use_bin_type=True))


def post(url: str, content: bytes) -> httpx.Response:
    return httpx.post(f"{url}/v1/synthesize", content=content, headers={"content-type": MSGPACK}, timeout=60)


def served(url: str, status: int) -> int:
    """Synthesize requests this replica answered with `status` (its own /metrics)."""
    text = httpx.get(f"{url}/metrics").text
    pattern = re.compile(rf'^quadsynth_requests_total{{.*route="/v1/synthesize",status="{status}"}} (\S+)$',
                         re.MULTILINE)
    return int(sum(float(v) for v in pattern.findall(text)))


def test_requests_and_a_stream_pass_through_and_spread_over_both_replicas(
        cluster: Cluster, herd: np.ndarray) -> None:
    url, replicas, _, _ = cluster
    before = [served(r, 200) for r in replicas]
    answers: list[httpx.Response] = []
    senders = [threading.Thread(target=lambda: answers.append(post(url, body(herd)))) for _ in range(6)]
    for s in senders:
        s.start()
    for s in senders:
        s.join(timeout=120)
    assert [a.status_code for a in answers] == [200] * 6
    assert len({a.content for a in answers}) == 1  # whichever replica answered: the same bytes
    spread = [served(r, 200) - b for r, b in zip(replicas, before, strict=True)]
    assert sum(spread) == 6 and min(spread) >= 1, spread

    with Client(url) as client:
        chunks = list(client.stream(herd, ids=[f"h{c}" for c in range(len(herd))], chunk_frames=40, seed=1))
        rest = client.synthesize(herd, ids=[f"h{c}" for c in range(len(herd))], seed=1)
    assert sum(chunk.root.shape[1] for chunk in chunks) == len(rest.characters[0].root)
    streamed = np.concatenate([chunk.gait for chunk in chunks], axis=1)
    np.testing.assert_array_equal(streamed, np.stack([ch.gait for ch in rest.characters]))

    with Client(url) as client, client.live([f"h{c}" for c in range(len(herd))], fps=60, seed=1) as session:
        live = session.push(herd[:, :60]) + session.push(herd[:, 60:]) + session.finish()
    assert sum(chunk.root.shape[1] for chunk in live) == herd.shape[1]  # a live session too


def test_an_oversized_body_is_refused_by_nginx_in_the_services_format(cluster: Cluster) -> None:
    url, _, _, _ = cluster
    response = post(url, b"\0" * (8 * 1024 * 1024 + 1))
    assert response.status_code == 413
    assert response.json()["error"] == {"status": 413, "field": "body",
                                        "message": "more than the limit of 8388608 bytes (max_body_bytes)"}


class Filled:
    """A replica with its worker held and its queue full: it answers 503 until released."""

    def __init__(self, replica: str, herd: np.ndarray) -> None:
        self.replica = replica
        self.answers: list[int] = []
        content = body(herd)

        def send() -> None:
            self.answers.append(post(replica, content).status_code)
        self.senders = [threading.Thread(target=send) for _ in range(1 + QUEUED)]

    def __enter__(self) -> Filled:
        assert httpx.post(f"{self.replica}/_test/hold").status_code == 200
        self.senders[0].start()
        while not httpx.get(f"{self.replica}/_test/held").json()["held"]:
            time.sleep(0.02)
        for s in self.senders[1:]:
            s.start()
        while in_flight(self.replica) < 1 + QUEUED:
            time.sleep(0.02)
        return self

    def __exit__(self, *exc: object) -> None:
        httpx.post(f"{self.replica}/_test/release")
        for s in self.senders:
            s.join(timeout=60)


def test_a_busy_or_missing_replica_is_retried_on_the_other(cluster: Cluster, herd: np.ndarray) -> None:
    """(Runs last: it stops a replica.)"""
    url, (busy, other), procs, log = cluster
    one = body(herd[:1])
    refused_before = served(busy, 503)
    with Filled(busy, herd[:1]) as filled:
        assert [post(url, one).status_code for _ in range(4)] == [200] * 4
        assert served(busy, 503) - refused_before >= 2  # nginx did try it, and went on to the other
        with Filled(other, herd[:1]):  # both full: the client gets 503 + Retry-After, not a 502
            response = post(url, one)
            assert response.status_code == 503 and response.headers["retry-after"] == "1"
            assert "max_in_flight + max_queued" in response.json()["error"]["message"]
    assert filled.answers == [200] * (1 + QUEUED)

    procs[0].terminate()  # gone: connection refused, nginx goes on to the other
    procs[0].wait(timeout=30)
    before = served(other, 200)
    port = busy.rsplit(":", 1)[1]
    refused_connects = log.read_text().count(f"127.0.0.1:{port}/v1/synthesize")
    assert [post(url, one).status_code for _ in range(20)] == [200] * 20
    assert served(other, 200) - before == 20
    # Passive health (max_fails=3): the dead replica is tried at most 3 times, not for each
    # request (least_conn alone tries it first for about every other one).
    assert log.read_text().count(f"127.0.0.1:{port}/v1/synthesize") - refused_connects <= 3
    procs[1].terminate()  # none left: nginx's own answer, in the service's format
    procs[1].wait(timeout=30)
    response = post(url, one)
    assert response.status_code == 503 and response.headers["retry-after"] == "1"
    assert response.json()["error"]["message"].startswith("no replica could take the request")
