"""Issue 34: what small requests must not do to a worker -- a client that does not read its
answer holds a bounded amount in it, and is cut off after ``send_timeout_s``; answers that do not
fit the memory budget are refused (503 now, 422 never); limits hold after resampling;
coordinates out of range are refused and no zero-norm quaternion leaves, on any encoding."""

from __future__ import annotations

import base64
import json
import socket
from collections.abc import Iterator
from typing import Any

import httpx
import msgpack
import numpy as np
import pytest

from api_schemas.wire import (
    BYTES_PER_JOINT_FRAME,
    ENCODING_ERROR,
    blob,
    decode_rotations,
    rotation_angle,
    unblob,
)
from service import budget
from synth_core.quality import herd_sim as crowd
from tests.helpers.servers import metric, running, wait_for

MSGPACK = "application/vnd.msgpack"
MB = 1 << 20
HORSE_JOINTS = 40
BUFFER = 4 * MB
# The answer a non-reading client asks for: f32, 60 x 2000 (an 80 MB answer).
STALLED = (60, 2000)
STALLED_ESTIMATE = budget.answer_bytes(*STALLED, HORSE_JOINTS, BYTES_PER_JOINT_FRAME["f32"], False, BUFFER)
BUDGET_MB = STALLED_ESTIMATE * 3 // 2 // MB  # room for one such answer, not two
LIMITS = {"QUADSYNTH_MAX_CHARACTER_FRAMES": "400000", "QUADSYNTH_MAX_IN_FLIGHT": "1",
          "QUADSYNTH_MAX_QUEUED": "4", "QUADSYNTH_MEMORY_BUDGET_MB": str(BUDGET_MB),
          "QUADSYNTH_ANSWER_BUFFER_BYTES": str(BUFFER), "QUADSYNTH_SEND_TIMEOUT_S": "5",
          "QUADSYNTH_BODY_TIMEOUT_S": "2"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("harden"), LIMITS) as (url, _):
        yield url


def batch(paths: np.ndarray, **options: Any) -> dict[str, Any]:
    return {"animal": "horse", "seed": 3, **options,
            "characters": [{"id": f"h{c}", "points": blob(p)} for c, p in enumerate(paths)]}


def post(url: str, body: dict[str, Any], as_json: bool = False) -> httpx.Response:
    if as_json:
        raw = json.dumps(body, default=lambda b: base64.b64encode(b).decode()).encode()
    else:
        raw = msgpack.packb(body, use_bin_type=True)
    return httpx.post(f"{url}/v1/synthesize", content=raw, timeout=120,
                      headers={"content-type": "application/json" if as_json else MSGPACK})


def refused(response: httpx.Response, status: int, field: str, *words: str) -> dict[str, Any]:
    assert response.status_code == status, (field, response.text[:300])
    error: dict[str, Any] = response.json()["error"]
    assert error["status"] == status and error["field"] == field, error
    for word in words:
        assert word in error["message"], error
    return error


def stalled_client(url: str, body: bytes) -> socket.socket:
    """A connection that sends its request and then reads nothing (a small receive buffer)."""
    host, port = url.removeprefix("http://").split(":")
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 * 1024)
    sock.connect((host, int(port)))
    head = (f"POST /v1/synthesize HTTP/1.1\r\nHost: {host}\r\nContent-Type: {MSGPACK}\r\n"
            f"Content-Length: {len(body)}\r\n\r\n").encode()
    sock.sendall(head + body)
    return sock


def test_a_client_that_does_not_read_holds_a_bounded_amount_then_is_cut_off(server: str) -> None:
    paths = crowd.simulate(*STALLED, seed=5).astype(np.float32)
    body = msgpack.packb(batch(paths, encoding="f32"), use_bin_type=True)
    answer_size = STALLED[0] * STALLED[1] * HORSE_JOINTS * 16
    produced = metric(server, "quadsynth_answer_bytes_produced_total")
    cancelled = metric(server, "quadsynth_cancelled_total")
    sock = stalled_client(server, body)
    try:
        wait_for(server, "quadsynth_answers_blocked", 1)  # the making waits for the socket
        made = metric(server, "quadsynth_answer_bytes_produced_total") - produced
        # The hand-over (4 MB, or one piece of ~7.8 MB) plus what the sockets' buffers took --
        # not the 77 MB answer an unbounded queue made at once.
        assert 0 < made <= 32 * MB < answer_size
        assert metric(server, "quadsynth_answer_bytes_waiting") <= 8 * MB
        assert metric(server, "quadsynth_in_flight") == 1
        assert metric(server, "quadsynth_memory_reserved_bytes") >= STALLED_ESTIMATE
        # Another answer of that size does not fit the memory budget beside it: 503, not queued.
        second = post(server, batch(paths, encoding="f32"))
        refused(second, 503, "", "memory_budget_mb")
        assert second.headers["retry-after"] == "1"
        # send_timeout_s (5 s) later the answer is cut short: its slot and memory are free.
        wait_for(server, "quadsynth_in_flight", 0, timeout=60)
        wait_for(server, "quadsynth_memory_reserved_bytes", 0)
        assert metric(server, "quadsynth_answers_blocked") == 0
        assert metric(server, "quadsynth_answer_bytes_produced_total") - produced <= 32 * MB
        assert metric(server, "quadsynth_cancelled_total") == cancelled + 1
    finally:
        sock.close()
    assert 'reason="memory"} 1' in httpx.get(f"{server}/metrics").text
    small = post(server, batch(paths[:2, :200]))
    assert small.status_code == 200 and len(msgpack.unpackb(small.content)["characters"]) == 2


def test_an_answer_that_could_never_fit_the_budget_is_refused_naming_it(server: str) -> None:
    # One character of 20,000 points resampled 2x, f32: its pieces alone are over the budget.
    path = crowd.simulate(1, 20_000, seed=1).astype(np.float32)
    assert budget.answer_bytes(1, 39_999, HORSE_JOINTS, 16, False, BUFFER) > BUDGET_MB * MB
    refused(post(server, batch(path, encoding="f32", min_resample_rate=2)), 422, "characters",
            "memory_budget_mb", f"budget of {BUDGET_MB} MB")


def test_the_frame_limit_holds_after_resampling(server: str) -> None:
    # Asked for: 51 x 1000 points resampled 8x -- 7,993 frames each, over the limit by the request alone.
    paths = crowd.simulate(51, 1000, seed=2).astype(np.float32)
    error = refused(post(server, batch(paths, min_resample_rate=8)), 422, "min_resample_rate",
                    "max_character_frames", "resampled 8x")
    assert "51 characters x 7993 frames" in error["message"]
    # Asked for with 'resample': characters twice as fast as the library's fastest gallop (scale 1)
    # get their paths resampled 2x -- 80 x 4000 frames fit the limit, 80 x 8000 do not.
    top = 2.0 * float(httpx.get(f"{server}/v1/libraries/horse").json()["gaits"][-1]["max_speed"])
    fast = np.zeros((80, 4000, 3), np.float32)
    fast[:, :, 2] = np.arange(4000) / 60.0 * top
    fast[:, :, 0] = np.arange(80)[:, None] * 3.0
    body = batch(fast, resample=True)
    for ch in body["characters"]:
        ch["scale"] = 1.0
    refused(post(server, body), 422, "characters", "max_character_frames", "resampled", "80 characters")
    # The same herd at half the speed needs no resampling and is answered.
    fast[:, :, 2] /= 4.0
    assert post(server, batch(fast, encoding="i16", resample=True)).status_code == 200


def test_coordinates_beyond_the_documented_range_are_refused_naming_the_character(server: str) -> None:
    paths = crowd.simulate(3, 120, seed=3).astype(np.float64)  # 1e39 is beyond float32 too
    for far in (2e6, 1e16, 1e39):
        moved = paths.copy()
        moved[1, :, 0] += far
        refused(post(server, batch(moved)), 422, "characters[1].points", "beyond the range", "1e+06 m")


@pytest.mark.parametrize("as_json", [False, True])
def test_no_zero_norm_or_non_finite_rotation_leaves_on_any_encoding(server: str, as_json: bool) -> None:
    """At the origin and at the edge of the documented range: every encoding decodes to unit
    quaternions, and i16 / s48 to the f32 answer within their documented error."""
    paths = crowd.simulate(3, 240, seed=4)
    for offset in (0.0, 9.9e5):
        moved = paths + np.array([offset, 0.0, -offset])
        decoded = {}
        for encoding in ("f32", "i16", "s48"):
            response = post(server, batch(moved, encoding=encoding), as_json)
            assert response.status_code == 200, response.text[:300]
            body = response.json() if as_json else msgpack.unpackb(response.content)
            for ch in body["characters"]:
                rot = ch["rotations"]
                data = base64.b64decode(rot["data"]) if as_json else rot["data"]
                packed = unblob(rot["dtype"], rot["shape"], data)
                if encoding == "f32":
                    norms = np.linalg.norm(packed.astype(np.float64), axis=-1)
                    assert np.isfinite(packed).all() and np.abs(norms - 1).max() < 1e-4, (offset, ch["id"])
                elif encoding == "i16":
                    norms = np.linalg.norm(packed.astype(np.float64), axis=-1) / 32767
                    assert np.abs(norms - 1).max() < 1e-3, (offset, ch["id"])
                decoded[(encoding, ch["id"])] = decode_rotations(packed, encoding)
        for (encoding, cid), q in decoded.items():
            worst = np.degrees(rotation_angle(decoded[("f32", cid)], q).max())
            assert worst <= ENCODING_ERROR[encoding][0], (offset, encoding, cid, worst)


def test_a_stalled_upload_gets_408_naming_the_body_timeout(server: str) -> None:
    host, port = server.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=30) as sock:
        sock.sendall((f"POST /v1/synthesize HTTP/1.1\r\nHost: {host}\r\nContent-Type: {MSGPACK}\r\n"
                      f"Content-Length: 100000\r\n\r\n").encode() + b"\x81" * 1000)  # and no more
        answer = b""
        while b"\r\n\r\n" not in answer or not answer.rstrip().endswith(b"}"):
            more = sock.recv(65536)
            if not more:
                break
            answer += more
    head, _, text = answer.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.1 408"), answer[:300]
    error = json.loads(text)["error"]
    assert error["field"] == "body" and "body_timeout_s" in error["message"]
    assert "1000 bytes" in error["message"]


def test_metrics_label_invented_methods_as_other_and_docs_by_route(server: str) -> None:
    for n in range(5):
        httpx.request(f"INVENTED{n}", f"{server}/livez")
    assert httpx.get(f"{server}/docs").status_code == 200
    assert httpx.get(f"{server}/openapi.json").status_code == 200
    text = httpx.get(f"{server}/metrics").text
    assert "INVENTED" not in text
    assert 'method="other",route="/livez"' in text
    assert 'method="GET",route="/docs",status="200"' in text
    assert 'method="GET",route="/openapi.json",status="200"' in text


def test_many_characters_are_validated_in_slices_naming_the_right_one() -> None:
    from api_schemas import SynthesizeRequest
    from service import jobs
    from service.errors import ApiError
    from service.settings import Settings

    points = blob(np.zeros((4, 3), np.float32))
    body: dict[str, Any] = {"characters": [{"id": f"c{c}", "points": dict(points)} for c in range(1000)]}
    req = jobs.validate(SynthesizeRequest, body, Settings(), {"horse": None})  # type: ignore[dict-item]
    assert req == SynthesizeRequest.model_validate(body)  # the same as in one piece
    body["characters"][700]["points"]["shape"] = "x"
    body["characters"][900]["extra"] = 1
    with pytest.raises(ApiError) as refused:
        jobs.validate(SynthesizeRequest, body, Settings(), {"horse": None})  # type: ignore[dict-item]
    assert (refused.value.status, refused.value.field) == (422, "characters[700].points.shape")
