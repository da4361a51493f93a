"""The delta encoding and the levels of detail through a real `quadsynth serve`: REST, WebSocket
batch and live give the f32 motion back within 0.1 mm after FK with delta; legs_spine sends fewer
joints with the feet where the full motion puts them; root_gait sends no rotations; frame_step
sends every k-th frame; far characters cost the link a fraction; bad values are refused naming
the field."""

from __future__ import annotations

import base64
from collections.abc import Iterator
from typing import Any

import msgpack
import numpy as np
import pytest
from websockets.sync.client import connect

from api_schemas.client import Client
from api_schemas.wire import blob, rotations_of
from bench.bench_wire import errors
from synth_core.motion.lod import detail_joints
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank
from tests.helpers.motion import assert_far_root
from tests.helpers.requests import LIMITS, post, refused
from tests.helpers.servers import running


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("lod"), LIMITS) as (url, _):
        yield url


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(4, 240, seed=11).astype(np.float32)


def within_budget(bank: Bank, root: np.ndarray, want: np.ndarray, got: np.ndarray, scales: Any) -> None:
    err = errors(bank.skeleton, root, want, got, np.asarray(scales, np.float64))
    assert err.max() <= 0.1, err.max()


def test_rest_delta_is_the_f32_motion_within_a_tenth_of_a_mm(server: str, herd: np.ndarray,
                                                             bank: Bank) -> None:
    with Client(server) as qs:
        exact = qs.synthesize(herd, seed=2, encoding="f32")
        small = qs.synthesize(herd, seed=2, encoding="delta")
    for a, b in zip(exact.characters, small.characters, strict=True):
        assert b.rotations.shape == a.rotations.shape
        within_budget(bank, a.root[None], a.rotations[None], b.rotations[None], [a.scale])
    s48 = post(server, {"animal": "horse", "seed": 2, "encoding": "s48",
                        "characters": [{"id": "a", "points": blob(herd[0])}]})
    delta = post(server, {"animal": "horse", "seed": 2, "encoding": "delta",
                          "characters": [{"id": "a", "points": blob(herd[0])}]})
    rot = {k: msgpack.unpackb(r.content)["characters"][0]["rotations"]
           for k, r in (("s48", s48), ("delta", delta))}
    assert len(rot["delta"]["data"]) * 3 <= len(rot["s48"]["data"])  # <= 2 bytes against 6
    assert rot["delta"]["decoded_shape"] == [240, bank.skeleton.n_joints, 4]
    as_json = post(server, {"animal": "horse", "seed": 2, "encoding": "delta",
                            "characters": [{"id": "a", "points": blob(herd[0])}]}, accept="application/json")
    text = as_json.json()["characters"][0]["rotations"]
    assert base64.b64decode(text["data"]) == rot["delta"]["data"]  # JSON: the same bytes, base64
    # Its length is known only once it is packed: it goes out chunked, as its characters are made.
    for r in (delta, as_json):
        assert "content-length" not in r.headers and r.headers["transfer-encoding"] == "chunked"


def test_rest_levels_of_detail(server: str, herd: np.ndarray, bank: Bank) -> None:
    sk = bank.skeleton
    with Client(server) as qs:
        full = qs.synthesize(herd, seed=2, encoding="f32")
        lod = qs.synthesize(herd, seed=2, encoding="f32", details=[None, "legs_spine", "root_gait", None],
                            lod={"frame_step": 2})
    assert lod.fps == full.fps / 2
    legs = detail_joints(sk, "legs_spine")
    for c, (a, b) in enumerate(zip(full.characters, lod.characters, strict=True)):
        if c == 2:  # root_gait: not posed (no foot lock), so the plan's root (tests/test_far_characters.py)
            assert_far_root(bank, b.root[None], a.root[None, ::2], np.array([a.scale]))
        else:
            np.testing.assert_array_equal(b.root, a.root[::2])
        np.testing.assert_array_equal(b.gait, a.gait[::2])
        assert b.rotations.shape == a.rotations[::2].shape  # identity filled in where not sent
        if c == 1:
            np.testing.assert_array_equal(b.rotations[:, legs], a.rotations[::2, legs])
            assert (b.rotations[:, [j for j in range(sk.n_joints) if j not in legs], 3] == 1).all()
        elif c == 2:
            assert (b.rotations[..., 3] == 1).all()
        else:
            np.testing.assert_array_equal(b.rotations, a.rotations[::2])
    raw = msgpack.unpackb(post(server, {"animal": "horse", "lod": {"detail": "root_gait"}, "characters": [
        {"id": "a", "points": blob(herd[0])}]}).content)
    sent = raw["characters"][0]["rotations"]
    assert sent["joints"] == [] and sent["data"] == b""


@pytest.mark.parametrize(("body", "field", "words"), [
    ({"lod": {"detail": "far"}}, "lod.detail", ("full",)),
    ({"lod": {"frame_step": 9}}, "lod.frame_step", ("8",)),
    ({"encoding": "d16"}, "encoding", ("delta",)),
])
def test_bad_lod_and_encoding_are_refused_naming_the_field(server: str, herd: np.ndarray,
                                                          body: dict[str, Any], field: str,
                                                          words: tuple[str, ...]) -> None:
    refused(post(server, {"animal": "horse", **body, "characters": [{"id": "a", "points": blob(herd[0])}]}),
            422, field, *words)
    half = {"id": "a", "points": blob(herd[0]), "detail": "half"}
    refused(post(server, {"animal": "horse", "characters": [half]}), 422, "characters[0].detail")


def test_ws_batch_with_delta_and_lod_gives_the_rest_motion(server: str, herd: np.ndarray, bank: Bank) -> None:
    details = ["full", "root_gait", "legs_spine", "root_gait"]
    with Client(server) as qs:
        rest = qs.synthesize(herd, seed=2, encoding="f32")
        chunks = list(qs.stream(herd, seed=2, encoding="delta", chunk_frames=40, details=details,
                                lod={"frame_step": 3}))
    head = chunks[0].header
    assert head["frame_step"] == 3 and head["details"] == details and head["fps"] == rest.fps / 3
    assert [c.start for c in chunks] == list(np.cumsum([0] + [c.root.shape[1] for c in chunks[:-1]]))
    root = np.concatenate([c.root for c in chunks], axis=1)
    rot = np.concatenate([c.rotations for c in chunks], axis=1)
    want_root = np.stack([ch.root[::3] for ch in rest.characters])
    want_rot = np.stack([ch.rotations[::3] for ch in rest.characters])
    posed = [0, 2]  # the root_gait rows are not posed: the plan's root (tests/test_far_characters.py)
    np.testing.assert_array_equal(root[posed], want_root[posed])
    far_scales = np.array([rest.characters[c].scale for c in (1, 3)])
    assert_far_root(bank, root[[1, 3]], want_root[[1, 3]], far_scales)
    within_budget(bank, want_root[:1], want_rot[:1], rot[:1], [rest.characters[0].scale])
    assert (rot[[1, 3]][..., 3] == 1).all()  # root_gait rows: identity, no data sent
    # A chunk with a row at full detail sends every joint of its rows (one array): legs_spine too.
    within_budget(bank, want_root[2:3], want_rot[2:3], rot[2:3], [rest.characters[2].scale])
    with Client(server) as qs:  # all at legs_spine: the legs and spine only, the rest identity
        legs_only = list(qs.stream(herd, seed=2, encoding="delta", chunk_frames=40,
                                   lod={"detail": "legs_spine"}))
    legs = detail_joints(bank.skeleton, "legs_spine")
    rot = np.concatenate([c.rotations for c in legs_only], axis=1)
    reduced = np.zeros_like(want_rot)
    reduced[..., 3] = 1.0
    reduced[:, :, legs] = want_rot[:, :, legs]
    within_budget(bank, want_root, reduced, rot[:, ::3], [c.scale for c in rest.characters])


def live_bytes(server: str, points: np.ndarray, details: list[str | None] | None = None,
               **options: Any) -> tuple[int, list[dict[str, Any]], list[float]]:
    """A live session's chunk bytes, chunk messages and character scales."""
    url = server.replace("http://", "ws://") + "/v1/stream"
    C = points.shape[0]
    characters = [{"id": f"c{c}"} | ({"detail": d} if d else {}) for c, d in enumerate(details or [None] * C)]
    with connect(url, compression=None, max_size=None) as ws:
        ws.send(msgpack.packb({"type": "live", "fps": 30, "seed": 1, **options, "characters": characters}))
        header = msgpack.unpackb(ws.recv())
        assert header["type"] == "start"
        ws.send(msgpack.packb({"type": "points", "points": blob(points)}))
        ws.send(msgpack.packb({"type": "finish"}))
        size, chunks = 0, list[dict[str, Any]]()
        while True:
            raw = ws.recv()
            message = msgpack.unpackb(raw)
            if message["type"] == "end":
                return size, chunks, [c["scale"] for c in header["characters"]]
            assert message["type"] == "chunk", message
            size += len(raw)
            chunks.append(message)
            ws.send(msgpack.packb({"type": "ack", "chunk": message["chunk"]}))


def test_live_far_characters_cost_the_link_a_fraction(server: str, bank: Bank) -> None:
    points = crowd.simulate(10, 150, seed=4, fps=30.0).astype(np.float32)
    full, _, _ = live_bytes(server, points, encoding="s48")
    delta, chunks, scales = live_bytes(server, points, encoding="delta")
    exact, exact_chunks, _ = live_bytes(server, points, encoding="f32")
    # A realistic mix: one in ten near (full), the rest far (root and gait).
    mixed, mixed_chunks, _ = live_bytes(server, points, ["full"] + [None] * 9, encoding="delta",
                                        lod={"detail": "root_gait"})
    assert delta * 2.5 <= full  # the rotations are most of a chunk: <= 2 of 6 bytes
    assert mixed * 4 <= delta
    J = bank.skeleton.n_joints
    q = np.concatenate([rotations_of(m["rotations"]) for m in chunks], axis=1)
    want = np.concatenate([rotations_of(m["rotations"]) for m in exact_chunks], axis=1)
    root = np.concatenate([np.frombuffer(m["root"]["data"], "<f4").reshape(m["root"]["shape"])
                           for m in exact_chunks], axis=1)
    within_budget(bank, root, want, q, scales)
    near = np.concatenate([rotations_of(m["rotations"], J, 10) for m in mixed_chunks], axis=1)
    assert all(m["rotations"]["characters"] == [0] for m in mixed_chunks)
    within_budget(bank, root[:1], want[:1], near[:1], scales[:1])
    assert (near[1:, ..., 3] == 1).all()


def test_a_live_lod_message_changes_the_details_from_the_next_chunk_on(server: str) -> None:
    points = crowd.simulate(3, 240, seed=8, fps=30.0).astype(np.float32)
    url = server.replace("http://", "ws://") + "/v1/stream"
    with connect(url, compression=None, max_size=None) as ws:
        ws.send(msgpack.packb({"type": "live", "fps": 30, "encoding": "delta",
                               "characters": [{"id": f"c{c}"} for c in range(3)]}))
        assert msgpack.unpackb(ws.recv())["type"] == "start"
        ws.send(msgpack.packb({"type": "points", "points": blob(points[:, :200])}))
        ws.send(msgpack.packb({"type": "lod", "details": [None, "root_gait", "legs_spine"]}))
        ws.send(msgpack.packb({"type": "points", "points": blob(points[:, 200:])}))
        ws.send(msgpack.packb({"type": "finish"}))
        rows = []
        while (message := msgpack.unpackb(ws.recv()))["type"] == "chunk":
            rows.append(message["rotations"].get("characters"))
            ws.send(msgpack.packb({"type": "ack", "chunk": message["chunk"]}))
        assert message["type"] == "end"
    assert rows[0] is None and rows[-1] == [0, 2]  # all three before, then the far one left out
    with connect(url, compression=None) as ws:
        ws.send(msgpack.packb({"type": "live", "characters": [{"id": "a"}, {"id": "b"}]}))
        assert msgpack.unpackb(ws.recv())["type"] == "start"
        ws.send(msgpack.packb({"type": "lod", "details": ["full", "near"]}))
        error = msgpack.unpackb(ws.recv())
        assert error["type"] == "error" and error["error"]["field"] == "details[1]", error
