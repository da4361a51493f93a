"""Service benchmark: ``quadsynth bench-service --json [--url URL]`` (or ``python -m
bench.bench_service``). Prints one JSON object; not a test.

Without ``--url`` it starts ``quadsynth serve`` on a free loopback port (the default library
directory) and stops it after. Figures (500 horses, crowd-sim, seed 0, msgpack, s48):

- ``rest_char_frames_per_s``: 500 x 500 frames through ``POST /v1/synthesize``, end to end over
  loopback HTTP (body out, whole answer in, read as the Python client reads it: into one buffer
  of its Content-Length), best of ``repeats``;
- ``ws_first_chunk_ms``: from sending a 500-character ``synthesize`` on ``/v1/stream`` to
  receiving its first 30-frame chunk, best of ``repeats`` (the session already open; the
  WebSocket figures read messages with :mod:`quadsynth.bench_ws`, as a game client would);
- ``ws_char_frames_per_s``: the same stream to its ``end``, acking every chunk;
- ``live_characters_30fps``: a live session of 4,000 horses fed 10 s of 30 fps points in
  half-second ticks as fast as the service takes them: the characters it would keep at 30 fps
  (4,000 x simulated seconds / wall seconds; the cost is linear in characters), best of
  ``LIVE_REPEATS`` sessions;
  ``live_latency_s_max``: with 70% of that many (at most 4,000) fed in real time, the longest
  from sending a frame's point to receiving its pose: the planner's look-ahead (bounded by the
  session's ``latency_frames``) plus the processing;
- ``bytes_per_joint_frame``: s48, measured on the answer;
- ``encodings`` (:func:`encodings`; alone: ``--encodings``, a minute): per rotation encoding the
  REST answer's rotation bytes per joint-frame (100 horses x 300 frames), and per encoding and
  level-of-detail mix a short live session's (1,000 horses, 4 s of 30 fps points, unpaced)
  bytes on the wire: per joint-frame and per character-frame (whole chunk messages: root, gait
  and contacts included), per second per character at 30 fps, and per second for 100,000 horses
  at 30 fps at that cost (``link_MB_s_100k_at_30fps``: the figure to hold against a 1 Gbit/s link's 125).
- ``live_scale`` (:mod:`quadsynth.bench_live_scale`; alone: ``--live-scale``, a few minutes): per
  encoding and level-of-detail mix, the largest herd held at 30 fps (sessions of 5,000 side by
  side, fed in real time) and its bytes per second on the wire, against the issue's targets.
- ``live_latency_per_mode`` (:mod:`quadsynth.bench_latency`; alone: ``--latency``, 20 s): per live
  mode, pose latency p50/p99/max in ms from sending a point (one a tick, 30 fps, real time) to
  receiving its pose.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import msgpack
import numpy as np

from api_schemas.client import read_body
from api_schemas.wire import blob
from quadsynth import bench_latency
from quadsynth.bench_ws import LeanSocket
from synth_core.quality import herd_sim as crowd

CHARACTERS, FRAMES = 500, 500
LIVE_CHARACTERS, LIVE_SECONDS, LIVE_TICK = 4000, 10.0, 15  # a tick: half a second of 30 fps points
# Runs of the REST and stream figures, the best kept: this shared VM's speed drifts (the same
# 500 x 500 request: 0.25-0.37 s in one minute), and a best of 4 measured the drift as often.
REPEATS = 10
# Live sessions run, the best kept: a fresh service's first big session runs ~20% slower than
# the next (12k against 15-19k here; a 1,000-horse warm-up did not change that, nor glibc's mmap
# threshold: not pinned down, likely memory the VM touches for the first time).
LIVE_REPEATS = 3


@contextmanager
def local_service() -> Iterator[str]:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    script = Path(sys.executable).with_name("quadsynth")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "quadsynth.cli"]
    proc = subprocess.Popen([*command, "serve", "--port", str(port), "--log-level", "warning"],
                            env=os.environ.copy(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 600  # the first start builds the libraries
        while True:
            if proc.poll() is not None:
                raise SystemExit("bench-service: `quadsynth serve` exited during start-up")
            try:
                if httpx.get(f"{url}/readyz", timeout=1).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline:
                raise SystemExit("bench-service: the service was not ready within 600 s")
            time.sleep(0.2)
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=60)


def rest(url: str, body: dict[str, Any], repeats: int) -> tuple[float, bytes | bytearray]:
    raw = msgpack.packb(body, use_bin_type=True)
    best = float("inf")
    content: bytes | bytearray = b""
    with httpx.Client(base_url=url, timeout=300) as client:
        for _ in range(repeats):
            t0 = time.perf_counter()
            with client.stream("POST", "/v1/synthesize", content=raw,
                               headers={"content-type": "application/vnd.msgpack"}) as response:
                content = read_body(response)  # as api_schemas.client.Client reads it
            best = min(best, time.perf_counter() - t0)
            if response.status_code != 200:
                raise SystemExit(f"bench-service: POST /v1/synthesize: {response.status_code} "
                                 f"{bytes(content[:300])!r}")
    return best, content


def stream(url: str, body: dict[str, Any], repeats: int) -> tuple[float, float]:
    """Best seconds to the first chunk and to the end (chunks read as :func:`live` reads them)."""
    raw = msgpack.packb({"type": "synthesize", "chunk_frames": 30, **body}, use_bin_type=True)
    first, whole = float("inf"), float("inf")
    with LeanSocket(url.replace("http://", "ws://") + "/v1/stream") as ws:
        for _ in range(repeats):
            t0 = time.perf_counter()
            ws.send(raw)
            while True:
                message = ws.recv_head()
                if message["type"] == "chunk":
                    if message["chunk"] == 0:
                        first = min(first, time.perf_counter() - t0)
                    ws.send(msgpack.packb({"type": "ack", "chunk": message["chunk"]}))
                elif message["type"] == "end":
                    whole = min(whole, time.perf_counter() - t0)
                    break
                elif message["type"] == "error":
                    raise SystemExit(f"bench-service: the stream failed: {message['error']}")
    return first, whole


def tick(paths: np.ndarray, i: int) -> np.ndarray:
    return np.ascontiguousarray(paths[:, i:i + LIVE_TICK])


def live(url: str, characters: int = LIVE_CHARACTERS, seconds: float = LIVE_SECONDS,
         paced: bool = False, options: dict[str, Any] | None = None,
         wire: dict[str, float] | None = None, paths: np.ndarray | None = None,
         ready: Callable[[], object] | None = None) -> tuple[float, float]:
    """A live session of ``characters`` fed ``seconds`` of 30 fps points, LIVE_TICK at a time --
    as fast as the service takes them, or ``paced`` as a simulation makes them -- acking every
    chunk, reading it as a game client would, into one buffer, not decoding it
    (:mod:`quadsynth.bench_ws`: the client must not take the cores it measures). Returns
    (characters it keeps at 30 fps, the longest from sending a frame's point to getting its pose).
    ``options``: the live message's (encoding, lod, characters' details); ``wire``: filled with
    the chunks' bytes and frames (and ``latency_s``, the session's); ``paths``: the points
    ``(characters, F, 3)`` (default: a crowd simulation's); ``ready``: called once the session
    has started, before its clock does (several sessions started together: see
    :mod:`quadsynth.bench_live_scale`)."""
    F = int(seconds * 30) + 1
    if paths is None:
        paths = crowd.simulate(characters, F, seed=0, fps=30.0).astype(np.float32)
    ticks = [msgpack.packb({"type": "points", "points": blob(tick(paths, i))},
                           use_bin_type=True)
             for i in range(0, F, LIVE_TICK)]
    opening = {"type": "live", "fps": 30, "seed": 1, "encoding": "s48",
               "characters": [{"id": f"h{c}"} for c in range(characters)], **(options or {})}
    sent_at: list[float] = []
    worst, frames = 0.0, 0
    with LeanSocket(url.replace("http://", "ws://") + "/v1/stream") as ws:
        ws.send(msgpack.packb(opening, use_bin_type=True))
        header = ws.recv_head()
        if header["type"] != "start":
            raise SystemExit(f"bench-service: the live session failed: {header}")
        settled = F - header["latency_frames"]  # frames sure to come before finish
        _started(header, wire, ready)
        t0 = time.perf_counter()
        while True:
            due = t0 + len(sent_at) * LIVE_TICK / 30 if paced else 0.0
            if len(sent_at) < len(ticks) and time.perf_counter() >= due:
                ws.send(ticks[len(sent_at)])
                sent_at.append(time.perf_counter())
                if len(sent_at) == len(ticks) and not paced:
                    ws.send(msgpack.packb({"type": "finish"}))
                continue
            try:
                message = ws.recv_head(timeout=0.01 if len(sent_at) < len(ticks) else None)
            except TimeoutError:
                continue
            if message["type"] == "chunk":
                frames += message["frames"]
                worst = max(worst, _chunk_taken(ws, message, frames, sent_at, wire))
                if paced and frames >= settled:
                    break
            elif message["type"] == "end":
                break
            else:
                raise SystemExit(f"bench-service: the live session failed: {message}")
        wall = time.perf_counter() - t0
    return characters * (F / 30) / wall, worst


def _chunk_taken(ws: LeanSocket, message: dict[str, Any], frames: int, sent_at: list[float],
                 wire: dict[str, float] | None) -> float:
    """A live chunk acked and counted (``frames``: sent so far, this one's included); returns the
    time from sending the point of its last frame to having its pose."""
    if wire is not None:
        wire["bytes"] = wire.get("bytes", 0) + ws.last_bytes
        wire["frames"] = frames
    sent = sent_at[min((frames - 1) // LIVE_TICK, len(sent_at) - 1)]
    taken = time.perf_counter() - sent
    ws.send(msgpack.packb({"type": "ack", "chunk": message["chunk"]}))
    return taken


def _started(header: dict[str, Any], wire: dict[str, float] | None,
             ready: Callable[[], object] | None) -> None:
    """A live session's start: its latency noted in ``wire``, ``ready`` called."""
    if wire is not None:
        wire["latency_s"] = header["latency_s"]
    if ready is not None:
        ready()


ENCODING_CHARACTERS, ENCODING_SECONDS = 1000, 4.0
# Level-of-detail mixes of a live herd: name -> the live message's options for C characters.
MIXES: dict[str, Callable[[int], dict[str, Any]]] = {
    "full": lambda C: {},
    "tenth_full_rest_root_gait": lambda C: {
        "lod": {"detail": "root_gait"},
        "characters": [{"id": f"h{c}"} | ({"detail": "full"} if c % 10 == 0 else {}) for c in range(C)]},
    "all_legs_spine": lambda C: {"lod": {"detail": "legs_spine"}},
}


def encodings(url: str) -> dict[str, Any]:
    """Bytes per joint-frame and per second for each encoding (and, live, level-of-detail mix)."""
    with httpx.Client(base_url=url, timeout=300) as client:
        joints = len(client.get("/v1/libraries/horse").json()["joint_names"])
    paths = crowd.simulate(100, 300, seed=0).astype(np.float32)
    out: dict[str, Any] = {"rest": {}, "live": {}}
    for enc in ("f32", "i16", "s48", "delta"):
        body = {"seed": 1, "encoding": enc,
                "characters": [{"id": f"h{c}", "points": blob(p)} for c, p in enumerate(paths)]}
        seconds, content = rest(url, body, 1)
        answer = msgpack.unpackb(content)
        rot = sum(len(ch["rotations"]["data"]) for ch in answer["characters"])
        cf = sum(ch["frames"] for ch in answer["characters"])
        out["rest"][enc] = {"bytes_per_joint_frame": round(rot / (cf * joints), 3),
                            "answer_bytes_per_char_frame": round(len(content) / cf, 1),
                            "seconds": round(seconds, 3)}
    for enc, mix in (("s48", "full"), ("delta", "full"), ("delta", "tenth_full_rest_root_gait"),
                     ("delta", "all_legs_spine")):
        wire: dict[str, float] = {}
        C = ENCODING_CHARACTERS
        live(url, C, ENCODING_SECONDS, options={"encoding": enc, **MIXES[mix](C)}, wire=wire)
        per_char_frame = wire["bytes"] / (wire["frames"] * C)
        # Bytes only: a 4 s session's speed says nothing (most of its frames wait for the finish).
        out["live"][f"{enc}/{mix}"] = {
            "wire_bytes_per_joint_frame": round(per_char_frame / joints, 3),
            "wire_bytes_per_char_frame": round(per_char_frame, 1),
            "wire_bytes_per_s_per_character_30fps": round(per_char_frame * 30),
            "link_MB_s_100k_at_30fps": round(per_char_frame * 30 * 100_000 / 1e6, 1)}
    return out


def run(url: str | None = None, repeats: int = REPEATS, only_encodings: bool = False,
        only_live_scale: bool = False, only_latency: bool = False) -> dict[str, Any]:
    from quadsynth.bench_live_scale import live_scale

    if url is None:
        with local_service() as local:
            return run(local, repeats, only_encodings, only_live_scale, only_latency)
    if only_encodings or only_live_scale or only_latency:
        return (({"encodings": encodings(url)} if only_encodings else {})
                | ({"live_scale": live_scale(url, log=_log)} if only_live_scale else {})
                | ({"live_latency_per_mode": bench_latency.per_mode(url)} if only_latency else {}))
    paths = crowd.simulate(CHARACTERS, FRAMES, seed=0).astype(np.float32)
    body = {"seed": 1, "encoding": "s48",
            "characters": [{"id": f"h{c}", "points": blob(p)} for c, p in enumerate(paths)]}
    seconds, content = rest(url, body, repeats)
    answer = msgpack.unpackb(content)
    frames = answer["characters"][0]["frames"]
    rotations = answer["characters"][0]["rotations"]
    joints = rotations["shape"][1]
    first, whole = stream(url, body, repeats)
    live_rate = max(live(url)[0] for _ in range(LIVE_REPEATS))
    paced = min(LIVE_CHARACTERS, int(0.7 * live_rate))
    _, live_latency = live(url, paced, paced=True)
    return {"rest_char_frames_per_s": round(CHARACTERS * FRAMES / seconds),
            "ws_first_chunk_ms": round(first * 1e3, 1),
            "ws_char_frames_per_s": round(CHARACTERS * FRAMES / whole),
            "live_characters_30fps": round(live_rate),
            "live_paced_characters": paced, "live_latency_s_max": round(live_latency, 3),
            "bytes_per_joint_frame": len(rotations["data"]) / (frames * joints),
            "rest_seconds": round(seconds, 3), "response_bytes": len(content),
            "encodings": encodings(url), "live_latency_per_mode": bench_latency.per_mode(url),
            "live_scale": live_scale(url, log=_log)}


def _log(line: str) -> None:
    print(line, file=sys.stderr, flush=True)  # progress; the JSON alone goes to stdout
