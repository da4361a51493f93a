"""SIGTERM as docs say, with several workers too: not ready at once, then new connections refused
(not taken and reset); WebSocket sessions waiting for the pool told 1001 with an error; the
cancelled counter counts WebSocket clients that leave mid-batch."""

from __future__ import annotations

import signal
import socket
import threading
import time
from pathlib import Path

import httpx
import msgpack
import numpy as np
import pytest

from api_schemas.wire import blob
from synth_core.quality import herd_sim as crowd
from tests.helpers.servers import free_port, running, start, wait_for, wait_until_live
from tests.helpers.stream import ws_url

MSGPACK = "application/vnd.msgpack"
# A request reset sooner than this after it was sent was reset by the listening socket's final
# close, not held in a queue nobody accepted from: a copy of the socket kept past the last worker's
# close (the supervisor's, issue 34) lasts until that worker exits, at least the 0.1 s uvicorn's
# shutdown sleeps after closing its listeners (0.15-0.27 s measured with service.supervisor not
# closing its copy).
RESET_AT_CLOSE_S = 0.1


def test_sigterm_with_two_workers_is_not_ready_at_once_then_refuses_connections(tmp_path: Path) -> None:
    port = free_port()
    proc = start(["--port", str(port), "--log-level", "warning"], tmp_path, workers=2)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_live(proc, url)
        ready = 0
        while ready < 20:  # both workers loaded: twenty answers in a row say so
            ready = ready + 1 if httpx.get(f"{url}/readyz").status_code == 200 else 0
        proc.send_signal(signal.SIGTERM)
        answers: list[int | str] = []
        took: list[float] = []  # how long each request took, s
        while not answers or answers[-1] != "refused":
            assert len(answers) < 2000, answers[-20:]
            t0 = time.monotonic()
            try:
                answers.append(httpx.get(f"{url}/readyz", timeout=5).status_code)
            except httpx.ConnectError:
                answers.append("refused")
            except httpx.TransportError as exc:  # taken, then reset or dropped
                answers.append(type(exc).__name__)
            took.append(time.monotonic() - t0)
        # Ready no more at once (one answer may have been on its way as the signal came), then
        # refused: no connection taken into the queue and reset. One exception the kernel makes
        # and no server can avoid: a connection completed in the instant between the last
        # worker's last accept() and its close() of the shared listening socket sits in the accept
        # queue, and Linux resets every queued connection when the socket's last descriptor
        # closes. That one is the request just before the first refusal and is reset at once; a
        # queue held open without accepting makes its request wait, and fails here.
        last = len(answers) - 2  # the answer before the refusal
        at_close = answers[last] not in (200, 503) and took[last] < RESET_AT_CLOSE_S
        rest = [a for i, a in enumerate(answers) if i >= 1 and not (at_close and i == last)]
        timed = list(zip(answers, took, strict=True))
        assert answers.count(200) <= 1 and set(rest) <= {503, "refused"}, timed
        for _ in range(5):
            with pytest.raises(httpx.ConnectError):
                httpx.get(f"{url}/readyz", timeout=5)
        assert proc.wait(timeout=60) in (0, -signal.SIGTERM)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_a_connection_taken_just_before_the_listeners_close_is_answered(tmp_path: Path) -> None:
    port = free_port()
    proc = start(["--port", str(port), "--log-level", "warning"], tmp_path)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_live(proc, url)
        early = socket.create_connection(("127.0.0.1", port), timeout=30)
        # Taken by the server: connections are accepted in the order they came, and a later one
        # has been answered.
        assert httpx.get(f"{url}/livez").status_code == 200
        proc.send_signal(signal.SIGTERM)
        until = time.monotonic() + 60
        while time.monotonic() < until:  # until the listeners are closed
            try:
                socket.create_connection(("127.0.0.1", port), timeout=5).close()
            except (ConnectionRefusedError, ConnectionResetError):  # (a probe in the queue as it closed)
                break
        early.sendall(b"GET /readyz HTTP/1.1\r\nHost: quadsynth\r\nConnection: close\r\n\r\n")
        answer = b""
        while chunk := early.recv(65536):
            answer += chunk
        assert answer.startswith(b"HTTP/1.1 503"), answer[:80]
        early.close()
        assert proc.wait(timeout=60) in (0, -signal.SIGTERM)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_a_websocket_session_waiting_for_the_pool_is_told_1001_on_sigterm(tmp_path: Path) -> None:
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    herd = crowd.simulate(2, 120, seed=1).astype(np.float32)
    body = {"animal": "horse", "characters": [{"id": f"h{c}", "points": blob(herd[c])} for c in range(2)]}
    env = {"QUADSYNTH_TEST_HOOKS": "1", "QUADSYNTH_MAX_IN_FLIGHT": "1", "QUADSYNTH_MAX_QUEUED": "2"}
    with running(tmp_path, env) as (url, proc):
        httpx.post(f"{url}/_test/hold")
        held: list[int] = []
        rest = threading.Thread(target=lambda: held.append(httpx.post(
            f"{url}/v1/synthesize", content=msgpack.packb(body, use_bin_type=True),
            headers={"content-type": MSGPACK}, timeout=60).status_code))
        rest.start()
        while not httpx.get(f"{url}/_test/held").json()["held"]:
            time.sleep(0.02)
        with connect(ws_url(url), compression=None) as ws:
            ws.send(msgpack.packb({"type": "synthesize", **body}, use_bin_type=True))
            wait_for(url, "quadsynth_in_flight", 2)  # the session queued behind the held request
            proc.send_signal(signal.SIGTERM)
            message = msgpack.unpackb(ws.recv(timeout=30))
            assert message["type"] == "error" and message["error"]["status"] == 503, message
            assert "shutting down" in message["error"]["message"]
            with pytest.raises(ConnectionClosed) as closed:
                ws.recv(timeout=30)
            assert closed.value.rcvd is not None and closed.value.rcvd.code == 1001
        rest.join(timeout=60)
        assert held == [200]  # the request in flight finished


def test_a_websocket_client_leaving_mid_batch_or_live_counts_as_cancelled(tmp_path: Path) -> None:
    from websockets.sync.client import connect

    herd = crowd.simulate(40, 2000, seed=2).astype(np.float32)
    body = {"type": "synthesize", "chunk_frames": 30, "animal": "horse",
            "characters": [{"id": f"h{c}", "points": blob(herd[c])} for c in range(len(herd))]}
    with running(tmp_path) as (url, _):
        with connect(ws_url(url), compression=None, max_size=None) as ws:
            ws.send(msgpack.packb(body, use_bin_type=True))
            assert msgpack.unpackb(ws.recv(timeout=60))["type"] == "start"
            assert msgpack.unpackb(ws.recv(timeout=60))["type"] == "chunk"  # then gone, no ack
        wait_for(url, "quadsynth_cancelled_total", 1)
        wait_for(url, "quadsynth_in_flight", 0)
        # A live session whose client leaves before its finish counts too.
        with connect(ws_url(url), compression=None, max_size=None) as ws:
            live = {"type": "live", "characters": [{"id": "a"}, {"id": "b"}]}
            ws.send(msgpack.packb(live, use_bin_type=True))
            assert msgpack.unpackb(ws.recv(timeout=60))["type"] == "start"
            ws.send(msgpack.packb({"type": "points", "points": blob(herd[:2, :30])}, use_bin_type=True))
        wait_for(url, "quadsynth_cancelled_total", 2)
