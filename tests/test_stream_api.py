"""WebSocket /v1/stream end to end against a real `quadsynth serve`: the same motion as REST,
typed errors and close codes, flow control, a slow consumer, a disconnect, SIGTERM."""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import msgpack
import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from api_schemas.client import Client
from api_schemas.wire import blob, unblob
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank
from synth_core.runtime.live import LiveSynth
from tests.helpers.requests import LIMITS, post
from tests.helpers.servers import free_port, metric, running, start, wait_until_ready
from tests.helpers.stream import closed_with, receive, send, stream_all, ws_url

STREAM_LIMITS = {**LIMITS, "QUADSYNTH_WS_WINDOW": "2", "QUADSYNTH_WS_SEND_TIMEOUT_S": "1.5"}


def launch(tmp: Path, env: dict[str, str]) -> tuple[Any, str]:
    port = free_port()
    proc = start(["--port", str(port), "--log-level", "warning"], tmp, env)
    url = f"http://127.0.0.1:{port}"
    wait_until_ready(proc, url)
    return proc, url


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("ws"), STREAM_LIMITS) as (url, _):
        yield url


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(5, 300, seed=2).astype(np.float32)


def batch(herd: np.ndarray, **options: Any) -> dict[str, Any]:
    # Characters of different lengths: each is answered at its own.
    return {"animal": "horse", "seed": 3, **options,
            "characters": [{"id": f"h{c}", "points": blob(herd[c, :300 - 40 * c])} for c in range(len(herd))]}


def test_stream_gives_the_motion_rest_gives(server: str, herd: np.ndarray) -> None:
    body = batch(herd, encoding="f32")
    rest = msgpack.unpackb(post(server, body).content)
    with connect(ws_url(server), compression=None) as ws:
        head, chunks = stream_all(ws, {**body, "chunk_frames": 45})
        again, _ = stream_all(ws, {**body, "chunk_frames": 300})  # a second batch, same session
    assert head["frames"] == 300 and head["chunks"] == len(chunks) == 7 and again["batch"] == head["batch"] + 1
    assert head["skeleton_id"] == rest["skeleton_id"] and head["resample_rate"] == rest["resample_rate"]
    assert [c["start"] for c in chunks] == list(range(0, 300, 45))
    joined = {name: np.concatenate([unblob(c[name]["dtype"], c[name]["shape"], c[name]["data"])
                                    for c in chunks], axis=1) for name in ("root", "rotations", "gait", "contacts")}
    for c, ch in enumerate(rest["characters"]):
        meta = head["characters"][c]
        assert meta == {"id": ch["id"], "scale": ch["scale"], "frames": ch["frames"]}
        assert ch["frames"] == 300 - 40 * c
        for name in joined:
            expected = unblob(ch[name]["dtype"], ch[name]["shape"], ch[name]["data"])
            got = joined[name][c, :ch["frames"]]
            assert np.array_equal(got, expected), name  # bit for bit (f32 rotations)


def test_ping_pong_and_cancel(server: str, herd: np.ndarray) -> None:
    with connect(ws_url(server)) as ws:
        send(ws, {"type": "ping", "time": 12.5})
        assert receive(ws) == {"type": "pong", "time": 12.5}
        send(ws, {"type": "synthesize", **batch(herd), "chunk_frames": 1})
        assert receive(ws)["type"] == "start"
        send(ws, {"type": "cancel"})
        while (m := receive(ws))["type"] == "chunk":
            send(ws, {"type": "ack", "chunk": m["chunk"]})
        assert m["type"] == "end" and m["cancelled"] and m["chunks"] < 300


@pytest.mark.parametrize(("message", "code", "status", "field", "words"), [
    ("text", 1007, 422, "message", ("binary msgpack",)),
    (b"\xc1", 1007, 422, "message", ("msgpack",)),
    ({"type": "dance"}, 1007, 422, "type", ("dance", "synthesize")),
    ({"type": "ack", "chunk": "x"}, 1007, 422, "chunk", ("integer",)),
    ({"type": "synthesize", "chunk_frames": 0}, 1007, 422, "chunk_frames", ("1 to 600",)),
    ({"type": "synthesize", "animal": "cat"}, 1007, 422, "characters", ("Field required",)),
])
def test_bad_messages_get_a_typed_error_then_a_close_code(server: str, message: Any, code: int, status: int,
                                                          field: str, words: tuple[str, ...]) -> None:
    with connect(ws_url(server)) as ws:
        if isinstance(message, dict):
            send(ws, message)
        else:
            ws.send(message)
        closed_with(ws, code, status, field, *words)


def test_bad_batches_name_the_character_and_the_limit(server: str, herd: np.ndarray) -> None:
    bad = herd.copy()
    bad[2, 100] = np.nan
    with connect(ws_url(server)) as ws:
        send(ws, {"type": "synthesize", **batch(bad)})
        closed_with(ws, 1007, 422, "characters[2].points", "NaN", "frame 100")
    many = {"characters": [{"id": str(i), "points": blob(herd[0, :10])} for i in range(41)]}
    with connect(ws_url(server)) as ws:
        send(ws, {"type": "synthesize", **many})
        closed_with(ws, 1007, 422, "characters", "max_characters")


def test_a_client_that_stops_acking_is_closed_with_1013(server: str, herd: np.ndarray) -> None:
    with connect(ws_url(server)) as ws:
        send(ws, {"type": "synthesize", **batch(herd), "chunk_frames": 10})
        assert receive(ws)["type"] == "start"
        got = []
        t0 = time.monotonic()
        while (m := receive(ws))["type"] == "chunk":
            got.append(m["chunk"])  # read, but never ack
        assert got == [0, 1]  # the window: at most 2 chunks unacknowledged
        assert m["type"] == "error" and m["error"]["status"] == 503 and "slow consumer" in m["error"]["message"]
        assert "ws_window" in m["error"]["message"] and time.monotonic() - t0 >= 1.4
        with pytest.raises(ConnectionClosed) as closed:
            ws.recv(timeout=10)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1013


def test_a_disconnect_mid_stream_stops_the_work(server: str) -> None:
    long = crowd.simulate(40, 2000, seed=1).astype(np.float32)
    body = {"animal": "horse", "chunk_frames": 1,
            "characters": [{"id": str(c), "points": blob(long[c, :500])} for c in range(40)]}
    with connect(ws_url(server)) as ws:
        send(ws, {"type": "synthesize", **body})
        assert receive(ws)["type"] == "start"
        m = receive(ws)
        send(ws, {"type": "ack", "chunk": m["chunk"]})
    # gone mid-stream, 499 chunks to go
    deadline = time.monotonic() + 5
    while metric(server, "quadsynth_websocket_sessions") > 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert metric(server, "quadsynth_websocket_sessions") == 0
    made = metric(server, "quadsynth_character_frames_total")
    time.sleep(0.5)
    assert metric(server, "quadsynth_character_frames_total") == made  # nothing left running
    assert metric(server, "quadsynth_in_flight") == 0
    assert httpx.get(f"{server}/livez").status_code == 200


def test_sigterm_closes_streams_with_1001(tmp_path: Path, herd: np.ndarray) -> None:
    proc, url = launch(tmp_path, STREAM_LIMITS)
    try:
        with connect(ws_url(url)) as ws:
            send(ws, {"type": "synthesize", **batch(herd), "chunk_frames": 10})
            assert receive(ws)["type"] == "start"
            proc.send_signal(signal.SIGTERM)
            while (m := receive(ws))["type"] == "chunk":
                pass  # not acking: the stream is mid-batch when the server drains
            assert m["type"] == "error" and m["error"]["status"] == 503 and "shutting down" in m["error"]["message"]
            with pytest.raises(ConnectionClosed) as closed:
                ws.recv(timeout=10)
            assert closed.value.rcvd is not None and closed.value.rcvd.code == 1001
        assert proc.wait(timeout=30) in (0, -signal.SIGTERM)
    finally:
        if proc.poll() is None:
            proc.kill()


def test_python_client_streams_the_motion_synthesize_returns(server: str, herd: np.ndarray) -> None:
    from api_schemas.client import Client, ServiceError

    with Client(server) as client:
        motion = client.synthesize(herd[:3], seed=9, encoding="i16")
        chunks = list(client.stream(herd[:3], seed=9, encoding="i16", chunk_frames=64))
        assert [c.start for c in chunks] == [0, 64, 128, 192, 256] and chunks[0].header["chunks"] == 5
        rotations = np.concatenate([c.rotations for c in chunks], axis=1)
        contacts = np.concatenate([c.contacts for c in chunks], axis=1)
        for c, ch in enumerate(motion.characters):
            assert np.array_equal(rotations[c], ch.rotations) and np.array_equal(contacts[c], ch.contacts)
        bad = herd[:2].copy()
        bad[1, 5] = np.inf
        with pytest.raises(ServiceError) as refused:
            list(client.stream(bad))
        assert refused.value.status == 422 and refused.value.field == "characters[1].points"


def test_one_batch_waits_at_most(server: str, herd: np.ndarray) -> None:
    with connect(ws_url(server)) as ws:
        for _ in range(3):  # one streams, one may wait, the third is refused
            send(ws, {"type": "synthesize", **batch(herd), "chunk_frames": 1})
        while (m := receive(ws))["type"] in ("start", "chunk"):
            pass
        assert m["type"] == "error" and m["error"]["field"] == "type" and "already waiting" in m["error"]["message"]
        with pytest.raises(ConnectionClosed) as closed:
            ws.recv(timeout=10)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008


def test_live_session_sends_the_frames_live_synthesis_makes(server: str, bank: Bank) -> None:

    herd = crowd.simulate(6, 240, seed=5, fps=30.0).astype(np.float32)
    chunks = []
    with Client(server) as client, client.live([f"h{c}" for c in range(6)], fps=30, seed=4,
                                               encoding="f32") as session:
        header = session.header
        assert header["mode"] == "live" and header["fps"] == 30.0 and header["library_fps"] == 60.0
        for i in range(0, 240, 12):
            chunks += session.push(herd[:, i:i + 12], wait=0.2)
            frames = sum(c.root.shape[1] for c in chunks)
            assert frames >= (i + 12) - header["latency_frames"] - 1  # within the documented latency
        rest = session.finish()
        chunks += rest
    assert [c.start for c in chunks] == list(np.cumsum([0] + [c.root.shape[1] for c in chunks[:-1]]))
    local = LiveSynth(bank, 6, 30.0, seed=4, scale_range=(0.8, 1.2))  # the server's built-in horse
    # The finish's frames (the latency's worth) come in chunks of a segment's frames at most.
    assert len(rest) >= 2 and max(c.root.shape[1] for c in chunks) <= local.window_frames
    assert [c["scale"] for c in header["characters"]] == local.scales.tolist()
    windows = [w for i in range(0, 240, 12) if (w := local.append(herd[:, i:i + 12])) is not None]
    windows.append(local.finish())
    want_root = np.concatenate([w.root_pos for w in windows], axis=1)
    want_rot = np.concatenate([w.rotations for w in windows], axis=1)
    got_root = np.concatenate([c.root for c in chunks], axis=1)
    got_rot = np.concatenate([c.rotations for c in chunks], axis=1)
    assert got_root.shape == want_root.shape == (6, 240, 3)
    np.testing.assert_allclose(got_root, want_root, atol=1e-5)
    np.testing.assert_allclose(got_rot, want_rot, atol=1e-5)
    np.testing.assert_array_equal(np.concatenate([c.gait for c in chunks], axis=1),
                                  np.concatenate([w.gait for w in windows], axis=1))


@contextmanager
def live_open(server: str, characters: int = 3) -> Iterator[ClientConnection]:
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "live", "characters": [{"id": f"c{c}"} for c in range(characters)]})
        assert receive(ws)["type"] == "start"
        yield ws


def test_live_refusals_name_the_field(server: str) -> None:
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "points", "points": blob(np.zeros((1, 2, 3), np.float32))})
        closed_with(ws, 1008, 422, "type", "without a live session")
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "live", "animal": "cat", "characters": [{"id": "a"}]})
        closed_with(ws, 1007, 404, "animal", "unknown animal 'cat'")
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "live", "characters": [{"id": f"c{c}"} for c in range(41)]})
        closed_with(ws, 1007, 422, "characters", "41 characters", "max_characters")
    with live_open(server) as ws:
        send(ws, {"type": "points", "points": blob(np.zeros((2, 4, 3), np.float32))})
        closed_with(ws, 1007, 422, "points.shape", "expected (3, n >= 1, 3)")
    with live_open(server) as ws:
        send(ws, {"type": "live", "characters": [{"id": "b"}]})
        closed_with(ws, 1008, 422, "type", "a live session is open")
    with live_open(server) as ws:
        bad = np.zeros((3, 4, 3), np.float32)
        bad[1, 2] = np.nan
        send(ws, {"type": "points", "points": blob(bad)})
        closed_with(ws, 1007, 422, "points[1]", "NaN or Inf")


def test_a_bad_velocity_is_refused_naming_the_field_and_the_limit(server: str) -> None:
    points = blob(np.cumsum(np.full((3, 4, 3), [0.02, 0.0, 0.0], np.float32), axis=1))
    nan, fast = np.zeros((3, 4, 2), np.float32), np.zeros((3, 4, 2), np.float32)
    nan[1, 2] = np.nan
    fast[2, 3] = [400.0, 0.0]
    for velocity, field, words in (
            (blob(np.zeros((3, 4, 3), np.float32)), "velocity.shape", ("expected (3, 4, 2)",)),
            (blob(np.zeros((3, 4, 2), np.int32)), "velocity.dtype", ("float32",)),
            ([1, 2], "velocity", ("a blob (characters, n, 2)",)),
            (blob(nan), "velocity[1]", ("NaN or Inf at its point 2",)),
            (blob(fast), "velocity[2]", ("400.0 m/s", "over the limit of 300 m/s"))):
        with live_open(server) as ws:
            send(ws, {"type": "points", "points": points, "velocity": velocity})
            closed_with(ws, 1007, 422, field, *words)


def test_a_low_latency_session_sends_the_frames_of_the_velocity_sent(server: str, bank: Bank) -> None:
    herd = crowd.simulate(3, 120, seed=5, fps=30.0).astype(np.float32)
    velocity = (np.gradient(herd[..., [0, 2]], axis=1) * 30.0).astype(np.float32)
    chunks = []
    with Client(server) as client, client.live(["a", "b", "c"], fps=30, seed=4, encoding="f32",
                                               mode="low_latency") as session:
        for i in range(0, 120, 6):
            chunks += session.push(herd[:, i:i + 6], wait=0.2, velocity=velocity[:, i:i + 6])
        chunks += session.finish()
    local = LiveSynth(bank, 3, 30.0, seed=4, scale_range=(0.8, 1.2), latency_ms=100.0)
    windows = [local.append(herd[:, i:i + 6], velocity=velocity[:, i:i + 6]) for i in range(0, 120, 6)]
    blind = LiveSynth(bank, 3, 30.0, seed=4, scale_range=(0.8, 1.2), latency_ms=100.0)  # none sent
    other = [blind.append(herd[:, i:i + 6]) for i in range(0, 120, 6)]
    want = np.concatenate([w.rotations for w in [*windows, local.finish()] if w is not None], axis=1)
    np.testing.assert_allclose(np.concatenate([c.rotations for c in chunks], axis=1), want, atol=1e-5)
    assert not np.allclose(np.concatenate([w.rotations for w in [*other, blind.finish()] if w is not None],
                                          axis=1), want, atol=1e-3)  # the velocity was read


def test_a_low_latency_session_sends_each_pose_within_its_budget(server: str) -> None:
    for bad, words in ((20, ("greater than or equal to 50",)), (5000, ("less than or equal to 2000",))):
        with connect(ws_url(server), compression=None) as ws:
            send(ws, {"type": "live", "latency_ms": bad, "characters": [{"id": "a"}]})
            closed_with(ws, 1007, 422, "latency_ms", *words)
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "live", "mode": "exact", "latency_ms": 100, "characters": [{"id": "a"}]})
        closed_with(ws, 1007, 422, "latency_ms", "only with mode low_latency")
    path = crowd.simulate(2, 120, seed=4, fps=30.0).astype(np.float32)
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "live", "fps": 30, "mode": "low_latency", "characters": [{"id": "a"}, {"id": "b"}]})
        start = receive(ws)
        assert (start["latency_mode"], start["latency_ms"], start["latency_frames"]) == ("low_latency", 100.0, 3)
        frames = 0
        for i in range(path.shape[1]):  # a point a message; each answered before the next is sent
            send(ws, {"type": "points", "points": blob(path[:, i:i + 1])})
            if i + 1 > start["latency_frames"]:  # from then on every point settles a frame
                chunk = receive(ws)
                assert chunk["type"] == "chunk" and chunk["start"] == frames, chunk
                frames += chunk["frames"]
                send(ws, {"type": "ack", "chunk": chunk["chunk"]})
            assert i + 1 - frames <= start["latency_frames"]  # points received, poses sent
        send(ws, {"type": "cancel"})


def test_live_cancel_ends_the_session_and_the_next_can_start(server: str) -> None:
    with live_open(server) as ws:
        path = np.cumsum(np.full((3, 400, 3), [0.02, 0.0, 0.0], np.float32), axis=1)
        send(ws, {"type": "points", "points": blob(path[:, :200])})
        send(ws, {"type": "cancel"})
        while (message := receive(ws))["type"] != "end":
            assert message["type"] == "chunk"
            send(ws, {"type": "ack", "chunk": message["chunk"]})
        assert message["cancelled"] is True
        send(ws, {"type": "live", "characters": [{"id": "again"}]})
        assert receive(ws)["type"] == "start"


def test_a_live_session_after_a_bigger_one_sends_the_same_bytes(server: str) -> None:
    """Live sessions pack their chunks over the buffers an earlier session of the worker used
    (service.batch_ws, synth_core.compiled.scratch.Shelf): after a bigger session, a session sends the
    bytes it sent before it."""
    def session(characters: int) -> list[bytes]:
        path = crowd.simulate(characters, 200, seed=2, fps=30.0).astype(np.float32)
        raw: list[bytes] = []
        with live_open(server, characters) as ws:
            for i in range(0, 200, 40):
                send(ws, {"type": "points", "points": blob(path[:, i:i + 40])})
            send(ws, {"type": "finish"})
            while True:
                data = ws.recv(timeout=30)
                assert isinstance(data, bytes)
                message = msgpack.unpackb(data)
                if message["type"] == "end":
                    return raw
                assert message["type"] == "chunk"
                raw.append(data)
                send(ws, {"type": "ack", "chunk": message["chunk"]})

    first = session(3)
    session(12)  # larger chunks: the buffers grow
    assert session(3) == first and len(first) >= 3


def test_the_benchmarks_lean_client_reads_what_the_service_sends(server: str) -> None:
    """quadsynth.bench_ws (bench-service's client: RFC 6455 framing on a plain socket, chunks
    read into one buffer, only their heads decoded) against the service: a stream's chunks as
    the websockets library reads them (the batch sent with the 64-bit length, masked over a
    length not a multiple of four), and a live session (16-bit lengths)."""
    from quadsynth import bench_service
    from quadsynth.bench_ws import LeanSocket

    paths = crowd.simulate(40, 500, seed=4).astype(np.float32)
    raw = msgpack.packb({"type": "synthesize", "chunk_frames": 70, "seed": 3,
                         "characters": [{"id": f"h{c}", "points": blob(p)} for c, p in enumerate(paths)]},
                        use_bin_type=True)
    assert len(raw) > 1 << 16 and len(raw) % 4
    heads = []
    with LeanSocket(ws_url(server)) as lean:
        lean.send(raw)
        while (head := lean.recv_head())["type"] != "end":
            heads.append(head)
            if head["type"] == "chunk":
                lean.send(msgpack.packb({"type": "ack", "chunk": head["chunk"]}))
    with connect(ws_url(server), compression=None, max_size=None) as ws:
        ws.send(raw)
        whole = []
        for _ in heads:
            whole.append(receive(ws))
            if whole[-1]["type"] == "chunk":
                send(ws, {"type": "ack", "chunk": whole[-1]["chunk"]})
    assert heads[0] == whole[0] and heads[0]["type"] == "start"  # not a chunk: decoded whole
    assert [h["chunk"] for h in heads[1:]] == list(range(len(heads) - 1)) == list(range(8))
    for head, message in zip(heads[1:], whole[1:], strict=True):
        assert head == {k: message[k] for k in ("type", "batch", "chunk", "start", "frames")}
    rate, latency = bench_service.live(server, characters=40, seconds=3.0)
    assert rate > 0 and 0 < latency < 60
