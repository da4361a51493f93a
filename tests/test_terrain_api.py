"""A terrain on the HTTP API (issue 33): sent with a batch, the bodies stand on it; a bad grid
is refused naming the field."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import msgpack
import numpy as np
import pytest
from websockets.sync.client import connect

from api_schemas.client import Client
from api_schemas.wire import blob, unblob
from synth_core.runtime.live import GROUND_BLEND_S
from synth_core.runtime.terrain import MAX_CELLS, HeightField
from tests.helpers.requests import LIMITS, batch, post, refused
from tests.helpers.servers import running
from tests.helpers.stream import closed_with, receive, send, stream_all, ws_url


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("terrain_api"), LIMITS) as (url, _):
        yield url


def _straight(n: int = 3, frames: int = 240, speed: float = 2.0) -> np.ndarray:
    x = np.arange(frames) * speed / 60.0
    paths = np.zeros((n, frames, 3), np.float32)
    paths[:, :, 0] = x
    paths[:, :, 2] = 3.0 * np.arange(n)[:, None]
    return paths


def _ground(heights: np.ndarray, origin: tuple[float, float] = (-10.0, -10.0), spacing: float = 0.5
            ) -> dict[str, Any]:
    return {"heights": blob(heights), "origin": list(origin), "spacing": spacing}


def test_a_batch_on_a_slope_stands_on_it(server: str) -> None:
    xs = np.arange(-10.0, 30.0, 0.5)
    heights = np.tile(0.3 * xs, (60, 1)).astype(np.float32)  # rises 30% along +x
    paths = _straight()
    answer = post(server, batch(paths, ground=_ground(heights)))
    assert answer.status_code == 200, answer.text[:300]
    field = HeightField.make(heights, (-10.0, -10.0), 0.5)
    flat = msgpack.unpackb(post(server, batch(paths)).content)["characters"]
    for on, off in zip(msgpack.unpackb(answer.content)["characters"], flat, strict=True):
        root, level = unblob(**on["root"]), unblob(**off["root"])
        above = root[:, 1] - field.sample(root[:, 0], root[:, 2])
        # The body keeps its height over the hill as over flat ground (its lowering on the slope:
        # a few cm), so it climbs 0.3 m per metre while the paths' y stays 0.
        assert np.abs(above - (level[:, 1] - 0.0)).max() < 0.15
        assert root[-1, 1] - root[0, 1] > 0.3 * (root[-1, 0] - root[0, 0]) - 0.15


def test_bad_grounds_are_refused_naming_the_field(server: str) -> None:
    paths = _straight(1)
    ok = np.zeros((4, 4), np.float32)
    nan = ok.copy()
    nan[2, 1] = np.nan
    too_big = {"dtype": "<f4", "shape": [MAX_CELLS + 1, 1], "data": b""}
    cases = [
        (_ground(nan), "ground.heights", "finite"),
        (_ground(ok[0]), "ground.heights.shape", "rows along z"),
        (_ground(ok[:1]), "ground.heights", "at least 2 x 2"),
        (_ground(ok.astype(np.int16)), "ground.heights.dtype", "float32"),
        ({**_ground(ok), "heights": too_big}, "ground.heights.shape", "over the limit"),
        ({**_ground(ok), "heights": {**blob(ok), "data": blob(ok)["data"][:-4]}}, "ground.heights.data",
         "bytes do not hold"),
        (_ground(ok, spacing=0.0), "ground.spacing", "greater than or equal"),
        ({**_ground(ok), "origin": [0.0]}, "ground.origin[1]", "required"),
        ({**_ground(ok), "slope": 3}, "ground.slope", "Extra inputs"),
    ]
    for ground, field, words in cases:
        refused(post(server, batch(paths, ground=ground)), 422, field, words)


def test_the_websocket_batch_on_a_slope_gives_what_rest_gives(server: str) -> None:
    xs = np.arange(-10.0, 30.0, 0.5)
    body = batch(_straight(2), encoding="f32", ground=_ground(np.tile(0.3 * xs, (60, 1)).astype(np.float32)))
    rest = msgpack.unpackb(post(server, body).content)
    with connect(ws_url(server), compression=None) as ws:
        _, chunks = stream_all(ws, {**body, "chunk_frames": 50})
    def array(b: dict[str, Any]) -> np.ndarray:
        return unblob(b["dtype"], b["shape"], b["data"])

    for name in ("root", "rotations"):
        joined = np.concatenate([array(c[name]) for c in chunks], axis=1)
        for c, ch in enumerate(rest["characters"]):
            want = array(ch[name])
            assert np.array_equal(joined[c], want), name


def test_a_live_session_takes_its_ground_once_at_the_start(server: str) -> None:
    xs = np.arange(-10.0, 30.0, 0.5)
    slope = _ground(np.tile(0.3 * xs, (60, 1)).astype(np.float32))
    with connect(ws_url(server), compression=None) as ws:
        bad = {**slope, "heights": blob(np.full((3, 3), np.nan, np.float32))}
        send(ws, {"type": "live", "ground": bad, "characters": [{"id": "a"}]})
        closed_with(ws, 1007, 422, "ground.heights", "finite")
    paths = _straight(2, 240)
    chunks = []
    with Client(server) as client, client.live(["a", "b"], fps=60, ground=slope, encoding="f32") as session:
        for i in range(0, 240, 20):
            chunks += session.push(paths[:, i:i + 20], wait=0.2)
        chunks += session.finish()
    root = np.concatenate([c.root for c in chunks], axis=1)
    assert root.shape[1] > 200
    field = HeightField.make(np.tile(0.3 * xs, (60, 1)), (-10.0, -10.0), 0.5)
    above = root[..., 1] - field.sample(root[..., 0], root[..., 2])
    assert 0.5 < above.min() and above.max() < 2.5  # standing on the slope (the paths' y is 0)


def test_a_live_sessions_ground_is_replaced_by_a_ground_message(server: str) -> None:
    """Flat at first (the points' y, 0), then a ground message puts a 30% slope under the frames
    rendered from then on, then `ground: null` gives the points' y back; a bad grid is refused
    naming the field, as in the opening message."""
    xs = np.arange(-10.0, 30.0, 0.5)
    heights = np.tile(0.3 * xs, (60, 1)).astype(np.float32)
    field = HeightField.make(heights, (-10.0, -10.0), 0.5)
    paths = _straight(2, 900)
    pieces: list[list[Any]] = [[], [], []]
    with Client(server) as client, client.live(["a", "b"], fps=60, encoding="f32") as session:
        for part, (a, b) in enumerate(((0, 300), (300, 600), (600, 900))):
            if part == 1:
                pieces[part] += session.set_ground(_ground(heights))
            if part == 2:
                pieces[part] += session.set_ground(None)
            for i in range(a, b, 20):
                pieces[part] += session.push(paths[:, i:i + 20], wait=0.2)
        pieces[2] += session.finish()
    roots = [np.concatenate([c.root for c in p], axis=1) for p in pieces]
    assert all(r.shape[1] > 100 for r in roots), [r.shape for r in roots]
    flat = roots[0][..., 1]
    # Frames rendered after the message: the frames of points sent before it too (the latency),
    # every one of them on the slope once it has faded in (GROUND_BLEND_S), which is over a metre
    # high under them (flat would miss it) -- and on its way there before, never past it.
    fade = int(np.ceil(GROUND_BLEND_S * 60))
    fading = roots[1][:, :fade]
    lift = fading[..., 1] - field.sample(fading[..., 0], fading[..., 2])
    assert lift.max() < flat.max() + 0.15  # never over the slope ...
    first = fading[:, 0, 1]
    assert flat.min() - 0.05 < first.min() and first.max() < flat.max() + 0.05  # ... from the flat
    on = roots[1][:, fade:]
    above = on[..., 1] - field.sample(on[..., 0], on[..., 2])
    assert flat.min() - 0.15 < above.min() and above.max() < flat.max() + 0.15, (above.min(), above.max())
    assert field.sample(on[..., 0], on[..., 2]).min() > 1.0
    back = roots[2][:, -60:, 1]  # flat again by the end (the change's own frames may still carry the slope)
    assert flat.min() - 0.03 < back.min() and back.max() < flat.max() + 0.03  # on the slope: over 3 m up
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "live", "characters": [{"id": "a"}]})
        assert receive(ws)["type"] == "start"
        send(ws, {"type": "ground", "ground": {**_ground(heights), "spacing": -1.0}})
        closed_with(ws, 1007, 422, "ground.spacing", "greater than")
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "live", "characters": [{"id": "a"}]})
        assert receive(ws)["type"] == "start"
        send(ws, {"type": "ground", "ground": _ground(np.full((3, 3), np.inf, np.float32))})
        closed_with(ws, 1007, 422, "ground.heights", "finite")
    with connect(ws_url(server), compression=None) as ws:
        send(ws, {"type": "ground", "ground": None})
        closed_with(ws, 1008, 422, "type", "without a live session")
