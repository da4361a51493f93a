"""The HTTP API end to end: a real `quadsynth serve` on loopback, small limits, every route and
every refusal with its status and the field or limit it names."""

from __future__ import annotations

import base64
import json
import platform
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import msgpack
import numpy as np
import pytest

from api_schemas.wire import ENCODING_ERROR, blob, decode_rotations, rotation_angle, unblob
from synth_core.quality import herd_sim as crowd
from tests.helpers.requests import LIMITS, MSGPACK, batch, post, refused
from tests.helpers.servers import metric, running


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("api"), LIMITS) as (url, _):
        yield url


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(6, 240, seed=0).astype(np.float32)


def as_json(body: dict[str, Any]) -> str:
    return json.dumps(body, default=lambda b: base64.b64encode(b).decode())


def test_synthesize_returns_motion_per_character_byte_identical_for_the_same_seed(server: str,
                                                                                   herd: np.ndarray) -> None:
    first = post(server, batch(herd))
    assert first.status_code == 200 and first.headers["content-type"] == MSGPACK
    assert first.headers["content-length"] == str(len(first.content))  # sent in pieces, length known
    body = msgpack.unpackb(first.content)
    assert body["resample_rate"] == 1.0 and body["encoding"] == "s48" and body["fps"] == 60.0
    library = httpx.get(f"{server}/v1/libraries/horse").json()
    assert body["skeleton_id"] == library["skeleton_id"]
    J = len(library["joint_names"])
    for c, ch in enumerate(body["characters"]):
        assert ch["id"] == f"h{c}" and ch["frames"] == 240 and 0.8 <= ch["scale"] <= 1.2
        rot = ch["rotations"]
        assert rot["shape"] == [240, J, 6] and len(rot["data"]) == 240 * J * 6
        q = decode_rotations(unblob(rot["dtype"], rot["shape"], rot["data"]), "s48")
        assert np.allclose(np.linalg.norm(q, axis=-1), 1, atol=1e-5)
        root = unblob(**ch["root"])
        assert np.linalg.norm(root[-1, [0, 2]] - herd[c, -1, [0, 2]]) < 0.1  # on its path at the end
        assert set(unblob(**ch["gait"]).tolist()) <= {0, 1, 2, 3, 4}
        assert unblob(**ch["contacts"]).max() <= 15
    again = post(server, batch(herd))
    assert again.content == first.content
    other = post(server, batch(herd, seed=4))
    assert other.content != first.content


def test_encodings_decode_to_the_same_motion_within_their_error(server: str, herd: np.ndarray) -> None:
    decoded = {}
    for encoding in ("f32", "i16", "s48"):
        body = msgpack.unpackb(post(server, batch(herd[:2], encoding=encoding)).content)
        rot = body["characters"][1]["rotations"]
        assert rot["encoding"] == encoding
        decoded[encoding] = decode_rotations(unblob(rot["dtype"], rot["shape"], rot["data"]), encoding)
    for encoding in ("i16", "s48"):
        worst = np.degrees(rotation_angle(decoded["f32"], decoded[encoding]).max())
        assert worst <= ENCODING_ERROR[encoding][0]


def test_json_in_and_out_and_accept_negotiation(server: str, herd: np.ndarray) -> None:
    body = batch(herd[:2, :100])
    response = httpx.post(f"{server}/v1/synthesize", content=as_json(body),
                          headers={"content-type": "application/json"}, timeout=60)
    assert response.status_code == 200 and response.headers["content-type"] == "application/json"
    ch = response.json()["characters"][0]
    data = base64.b64decode(ch["root"]["data"])
    assert len(data) == 100 * 3 * 4
    packed = post(server, body, accept=MSGPACK)
    assert unblob(**msgpack.unpackb(packed.content)["characters"][0]["root"]).tobytes() == data
    for kind in ("application/x-msgpack", "application/msgpack"):
        assert post(server, body, **{"content-type": kind}).status_code == 200
    assert post(server, body, accept="application/json").headers["content-type"] == "application/json"


def test_characters_of_different_lengths_come_back_at_their_own_length(server: str, herd: np.ndarray) -> None:
    body = {"characters": [{"id": "long", "points": blob(herd[0])}, {"id": "short", "points": blob(herd[1, :61])}],
            "fps": 30.0}
    out = msgpack.unpackb(post(server, body).content)["characters"]
    assert [c["frames"] for c in out] == [479, 121]  # 30 -> 60 fps
    assert out[1]["root"]["shape"] == [121, 3]


def test_bad_input_is_refused_naming_the_field(server: str, herd: np.ndarray) -> None:
    nan = herd[:2].copy()
    nan[1, 7, 0] = np.nan
    jump = herd[:2].copy()
    jump[0, 100:] += 50.0
    ok = blob(herd[0])
    cases = [
        (b"\xc1", 422, "body", "not valid msgpack"),
        (msgpack.packb([1, 2]), 422, "body", "expected an object"),
        ({"characters": []}, 422, "characters", "at least 1"),
        ({"characters": [{"id": "a"}]}, 422, "characters[0].points", "required"),
        ({"animal": "cat", "characters": [{"id": "a", "points": ok}]}, 404, "animal", "unknown animal 'cat'"),
        ({"characters": [{"id": "a", "points": ok, "scale": 0}]}, 422, "characters[0].scale", "greater than 0"),
        ({"characters": [{"id": "a", "points": ok, "scale": -2}]}, 422, "characters[0].scale", "greater than 0"),
        ({"characters": [{"id": "a", "points": blob(herd[0, :1])}]}, 422, "characters[0].points", "at least 2"),
        ({"characters": [{"id": "a", "points": blob(herd[0].astype(np.int16))}]}, 422,
         "characters[0].points.dtype", "float32"),
        ({"characters": [{"id": "a", "points": blob(herd[0, :, :2])}]}, 422, "characters[0].points.shape",
         "(frames, 3)"),
        ({"characters": [{"id": "a", "points": {**ok, "data": ok["data"][:-4]}}]}, 422,
         "characters[0].points.data", "bytes do not hold"),
        ({"characters": [{"id": "a", "points": ok}, {"id": "a", "points": ok}]}, 422, "characters[1].id", "also"),
        (batch(nan), 422, "characters[1].points", "NaN or Inf at frame 7"),
        (batch(jump), 422, "characters[0].points", "teleport"),
        ({"characters": [{"id": "a", "points": blob(herd[0] * 50)}]}, 422, "characters[0].points", "m/s"),
        ({"encoding": "png", "characters": [{"id": "a", "points": ok}]}, 422, "encoding", "'f32', 'i16', 's48' or 'delta'"),
        ({"fps": -1, "characters": [{"id": "a", "points": ok}]}, 422, "fps", "greater than 0"),
        ({"characters": [{"id": "a", "points": ok}], "colour": "red"}, 422, "colour", "Extra inputs"),
    ]
    for body, status, field, words in cases:
        refused(post(server, body), status, field, words)
    refused(httpx.post(f"{server}/v1/synthesize", content=b"{", headers={"content-type": "application/json"}),
            422, "body", "not valid JSON")
    refused(httpx.post(f"{server}/v1/synthesize", content=b"x", headers={"content-type": "text/csv"}),
            415, "Content-Type", "text/csv")


def test_skip_invalid_keeps_the_others_work(server: str, herd: np.ndarray) -> None:
    nan = herd[:3].copy()
    nan[1, 7, 0] = np.nan
    body = msgpack.unpackb(post(server, batch(nan, skip_invalid=True)).content)
    assert [c["id"] for c in body["characters"]] == ["h0", "h2"]
    assert body["skipped"] == [{"id": "h1", "index": 1, "reason": "positions: NaN or Inf at frame 7"}]


def test_a_character_too_fast_keeps_the_clock_and_is_warned_of_unless_resampling_is_asked(
        server: str, herd: np.ndarray) -> None:
    fast = herd[:3].copy()
    fast[2] = fast[2, :1] + (fast[2] - fast[2, :1]) * 6.0  # far beyond the horse's gallop
    for encoding in ("s48", "f32"):
        body = msgpack.unpackb(post(server, batch(fast, encoding=encoding)).content)
        assert body["resample_rate"] == 1.0 and [c["frames"] for c in body["characters"]] == [240] * 3
        assert [(w["id"], w["index"]) for w in body["warnings"]] == [("h2", 2)]
        assert "moves at" in body["warnings"][0]["reason"] and "resample" in body["warnings"][0]["reason"]
        assert body["skipped"] == []
    resampled = msgpack.unpackb(post(server, batch(fast, resample=True)).content)
    assert resampled["resample_rate"] > 1.5 and resampled["warnings"] == []
    assert resampled["characters"][0]["frames"] > 240
    as_text = httpx.post(f"{server}/v1/synthesize", content=as_json(batch(fast, encoding="f32")),
                         headers={"content-type": "application/json"}, timeout=60).json()
    assert [w["id"] for w in as_text["warnings"]] == ["h2"]


def test_limits_are_published_and_enforced(server: str, herd: np.ndarray) -> None:
    limits = httpx.get(f"{server}/v1/limits").json()
    assert limits["max_characters"] == 40 and limits["max_body_bytes"] == 1024 * 1024
    assert limits["encodings"]["s48"]["bytes_per_joint_frame"] == 6
    many = {"characters": [{"id": str(c), "points": blob(herd[0, :10])} for c in range(41)]}
    refused(post(server, many), 422, "characters", "41 characters", "max_characters")
    long = np.repeat(herd[:1], 9, axis=1)[:, :2001]
    refused(post(server, batch(long)), 422, "characters[0].points", "2001 points", "max_frames")
    line = np.zeros((600, 3), np.float32)
    line[:, 2] = np.linspace(0, 10, 600)
    wide = {"characters": [{"id": str(c), "points": blob(line)} for c in range(40)]}
    refused(post(server, wide), 422, "characters", "24000 character-frames", "max_character_frames")
    refused(post(server, b"\0" * (1024 * 1024 + 1)), 413, "body", "max_body_bytes")

    def chunked() -> Iterator[bytes]:  # no Content-Length: refused while reading
        for _ in range(40):
            yield b"\0" * 65536

    response = httpx.post(f"{server}/v1/synthesize", content=chunked(), headers={"content-type": MSGPACK})
    refused(response, 413, "body", "max_body_bytes")


def test_libraries_and_docs(server: str) -> None:
    detail = httpx.get(f"{server}/v1/libraries/dog").json()
    J = len(detail["joint_names"])
    assert len(detail["parents"]) == J and len(detail["offsets"]) == J and detail["parents"][0] == -1
    assert all(p < j for j, p in enumerate(detail["parents"]))
    assert [g["name"] for g in detail["gaits"]] == ["walk", "trot", "canter", "gallop"]
    assert all(g["min_speed"] < g["max_speed"] for g in detail["gaits"])
    refused(httpx.get(f"{server}/v1/libraries/cat"), 404, "animal", "unknown animal 'cat'")
    spec = httpx.get(f"{server}/openapi.json").json()
    route = spec["paths"]["/v1/synthesize"]["post"]
    assert set(route["requestBody"]["content"]) == {MSGPACK, "application/json"}
    schemas = spec["components"]["schemas"]  # every body's $ref resolves, down to the blobs
    for ref in (route["requestBody"]["content"][MSGPACK]["schema"]["$ref"],
                route["responses"]["200"]["content"][MSGPACK]["schema"]["$ref"]):
        assert ref.rsplit("/", 1)[1] in schemas
    assert {"CharacterIn", "CharacterOut", "Blob", "PackedRotations"} <= set(schemas)
    assert {"200", "413", "415", "422", "503", "504"} <= set(route["responses"])
    assert {"/v1/limits", "/v1/libraries/{animal}", "/metrics", "/readyz", "/livez"} <= set(spec["paths"])
    assert httpx.get(f"{server}/docs").status_code == 200


def test_library_mesh_is_a_skinned_glb_on_the_listed_joints(server: str) -> None:
    import pygltflib

    for animal in ("horse", "dog"):
        detail = httpx.get(f"{server}/v1/libraries/{animal}").json()
        assert detail["mesh_url"] == f"/v1/libraries/{animal}/mesh.glb"
        response = httpx.get(server + detail["mesh_url"])
        assert response.status_code == 200 and response.headers["content-type"] == "model/gltf-binary"
        gltf = pygltflib.GLTF2.load_from_bytes(response.content)
        J = len(detail["joint_names"])
        assert [n.name for n in gltf.nodes[:J]] == detail["joint_names"]
        assert len(gltf.skins) == 1 and gltf.skins[0].joints == list(range(J))
        assert len(gltf.meshes) == 1 and gltf.nodes[J].mesh == 0 and gltf.nodes[J].skin == 0
    refused(httpx.get(f"{server}/v1/libraries/cat/mesh.glb"), 404, "animal", "unknown animal 'cat'")
    spec = httpx.get(f"{server}/openapi.json").json()
    assert "model/gltf-binary" in spec["paths"]["/v1/libraries/{animal}/mesh.glb"]["get"]["responses"]["200"]["content"]


def test_metrics_count_requests_and_character_frames(server: str, herd: np.ndarray) -> None:
    def value(text: str, prefix: str) -> float:
        return sum(float(line.rsplit(" ", 1)[1]) for line in text.splitlines() if line.startswith(prefix))

    before = httpx.get(f"{server}/metrics").text
    post(server, batch(herd[:2, :50]))
    post(server, {"characters": []})
    after = httpx.get(f"{server}/metrics").text
    frames = "quadsynth_character_frames_total"
    assert value(after, frames) - value(before, frames) == 100
    ok = 'quadsynth_requests_total{pid='
    assert value(after, ok) - value(before, ok) >= 3
    assert 'route="/v1/synthesize",status="422"' in after
    assert "quadsynth_synthesis_seconds_count" in after and "quadsynth_in_flight" in after
    assert value(after, 'python_gc_collections_total{pid=') > 0
    # What start-up made (libraries, kernels, frameworks) is frozen out of full collections.
    assert value(after, "quadsynth_gc_frozen_objects") > 50_000
    # Freed memory kept, no huge pages (service.memory): on by default.
    if platform.system() == "Linux" and platform.libc_ver()[0] == "glibc":
        assert value(after, 'quadsynth_memory_tuning{pid=') == 2


def test_overload_gets_503_with_retry_after_while_livez_stays_fast(server: str, herd: np.ndarray) -> None:
    assert httpx.post(f"{server}/_test/hold").status_code == 200
    results: list[int] = []
    workers = [threading.Thread(target=lambda: results.append(post(server, batch(herd[:1, :60])).status_code))
               for _ in range(2)]
    try:
        workers[0].start()  # runs (and waits on the hold)
        while not httpx.get(f"{server}/_test/held").json()["held"]:
            time.sleep(0.02)
        workers[1].start()  # queues
        time.sleep(0.3)
        response = post(server, batch(herd[:1, :60]))
        refused(response, 503, "", "max_in_flight + max_queued")
        assert response.headers["retry-after"] == "1"
        for _ in range(5):
            t0 = time.perf_counter()
            assert httpx.get(f"{server}/livez").status_code == 200
            assert time.perf_counter() - t0 < 0.2
        assert httpx.get(f"{server}/metrics").status_code == 200
    finally:
        httpx.post(f"{server}/_test/release")
        for w in workers:
            w.join(timeout=60)
    assert results == [200, 200]


def test_past_the_deadline_gets_504_and_the_worker_is_free_again(tmp_path: Path, herd: np.ndarray) -> None:
    with running(tmp_path, {**LIMITS, "QUADSYNTH_DEADLINE_S": "1"}) as (url, _):
        httpx.post(f"{url}/_test/hold")
        t0 = time.perf_counter()
        late = post(url, batch(herd[:2, :80]))
        refused(late, 504, "", "deadline of 1 s", "deadline_s")
        assert 1.0 <= time.perf_counter() - t0 < 5.0
        refused(httpx.post(f"{url}/v1/synthesize", content=as_json(batch(herd[:2, :80])), timeout=60,
                           headers={"content-type": "application/json"}), 504, "", "deadline_s")
        httpx.post(f"{url}/_test/release")
        # The abandoned work stops and gives its slot back: the next request is answered.
        answer = post(url, batch(herd[:2, :80]))
        assert answer.status_code == 200 and len(msgpack.unpackb(answer.content)["characters"]) == 2
        assert 'reason="deadline"} 2' in httpx.get(f"{url}/metrics").text
        assert metric(url, "quadsynth_cancelled_total") == 1  # the held one; the queued one never ran


@pytest.mark.parametrize("encoding", ["s48", "delta"])
def test_a_client_leaving_mid_answer_stops_the_work(tmp_path: Path, encoding: str) -> None:
    """The answer goes out while it is made: a client that reads its first bytes and hangs up
    stops the synthesis at its next chunk of characters (counted as cancelled, not as
    character-frames made), nothing is left running, and the worker takes the next request.
    delta too, whose length is known only once it is all packed: it goes out chunked."""
    big = crowd.simulate(600, 1000, seed=2).astype(np.float32)  # a 7.2 MB body: ~45 chunks of work
    with running(tmp_path, {"QUADSYNTH_MAX_IN_FLIGHT": "1", "QUADSYNTH_MAX_QUEUED": "1"}) as (url, _):
        raw = msgpack.packb({**batch(big), "encoding": encoding}, use_bin_type=True)
        with httpx.Client(timeout=60) as client, client.stream(
                "POST", f"{url}/v1/synthesize", content=raw, headers={"content-type": MSGPACK}) as response:
            assert response.status_code == 200
            first = next(response.iter_raw())
            if encoding == "delta":
                assert 0 < len(first) and response.headers["transfer-encoding"] == "chunked"
            else:
                assert 0 < len(first) < int(response.headers["content-length"])
        # gone: the connection closed with most of the answer still to come
        deadline = time.monotonic() + 30
        while metric(url, "quadsynth_cancelled_total") < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert metric(url, "quadsynth_cancelled_total") == 1
        while metric(url, "quadsynth_in_flight") > 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert metric(url, "quadsynth_in_flight") == 0
        assert metric(url, "quadsynth_character_frames_total") == 0
        answer = post(url, batch(big[:2, :100]))
        assert answer.status_code == 200 and len(msgpack.unpackb(answer.content)["characters"]) == 2
        assert metric(url, "quadsynth_character_frames_total") == 200
        assert metric(url, "quadsynth_cancelled_total") == 1


def test_sigterm_lets_the_request_in_flight_finish(tmp_path: Path, herd: np.ndarray) -> None:
    with running(tmp_path, LIMITS) as (url, proc):
        httpx.post(f"{url}/_test/hold")
        results: list[httpx.Response] = []
        worker = threading.Thread(target=lambda: results.append(post(url, batch(herd[:2, :80]))))
        worker.start()
        while not httpx.get(f"{url}/_test/held").json()["held"]:
            time.sleep(0.02)
        proc.send_signal(signal.SIGTERM)
        time.sleep(0.5)
        assert proc.poll() is None  # still draining: the request is in flight
        with pytest.raises(httpx.TransportError):  # and no new connection is taken
            httpx.get(f"{url}/livez", timeout=2)
        # Release through the in-flight worker's own event: the hold route is unreachable now,
        # so the test hook also lets go at shutdown (see State); wait for the answer.
        worker.join(timeout=60)
        assert results and results[0].status_code == 200
        assert len(msgpack.unpackb(results[0].content)["characters"]) == 2
        # uvicorn drains, then re-raises the SIGTERM it caught: the process ends by that signal.
        assert proc.wait(timeout=30) in (0, -signal.SIGTERM)


def test_python_client_gives_the_motion_synthesize_gives_locally(server: str, herd: np.ndarray) -> None:
    import asyncio

    from api_schemas.client import AsyncClient, Client, ServiceError, read_body
    from synth_core.build.animals import build_builtin
    from synth_core.runtime.bank import build_bank
    from synth_core.runtime.synthesis import Options, synthesize

    with Client(server) as qs:
        motion = qs.synthesize(herd[:3], ids=["a", "b", "c"], scales=[1.1, None, 0.9], seed=5, encoding="f32")
        assert [c.id for c in motion.characters] == ["a", "b", "c"]
        with pytest.raises(ServiceError, match="404 animal: unknown animal 'cat'"):
            qs.synthesize(herd[:1], animal="cat")
    local = synthesize(build_bank(build_builtin("horse")), herd[:3].astype(np.float64), 60.0,
                       [1.1, np.nan, 0.9], Options(seed=5, scale_range=(0.8, 1.2)))
    for c, ch in enumerate(motion.characters):
        assert ch.scale == pytest.approx(local.scales[c])
        assert np.abs(ch.root - local.root_pos[c]).max() < 1e-5
        assert np.degrees(rotation_angle(ch.rotations, local.rotations[c]).max()) < 1e-3
        assert np.array_equal(ch.contacts, local.contacts[c]) and np.array_equal(ch.gait, local.gait[c])

    async def over_asyncio() -> None:
        async with AsyncClient(server) as qs:
            again = await qs.synthesize(herd[:3], ids=["a", "b", "c"], scales=[1.1, None, 0.9], seed=5,
                                        encoding="s48")
        worst = max(np.degrees(rotation_angle(a.rotations, b.rotations).max())
                    for a, b in zip(again.characters, motion.characters, strict=True))
        assert worst <= ENCODING_ERROR["s48"][0]

    asyncio.run(over_asyncio())
    # The client reads an answer into one buffer of its Content-Length: the same bytes.
    raw = msgpack.packb(batch(herd[:3]), use_bin_type=True)
    with httpx.Client(base_url=server, timeout=60) as http:
        with http.stream("POST", "/v1/synthesize", content=raw, headers={"content-type": MSGPACK}) as r:
            streamed = read_body(r)
        assert isinstance(streamed, bytearray) and len(streamed) == int(r.headers["content-length"])
        assert streamed == http.post("/v1/synthesize", content=raw, headers={"content-type": MSGPACK}).content
