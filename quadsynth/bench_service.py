"""Service benchmark: ``quadsynth bench-service --json [--url URL]`` (or ``python -m
bench.bench_service``). Prints one JSON object; not a test.

Without ``--url`` it starts ``quadsynth serve`` on a free loopback port (the default library
directory) and stops it after. Figures (500 horses, crowd-sim, seed 0, msgpack, s48):

- ``rest_char_frames_per_s``: 500 x 500 frames through ``POST /v1/synthesize``, end to end over
  loopback HTTP (body out, whole answer in), best of ``repeats``;
- ``ws_first_chunk_ms``: from sending a 500-character ``synthesize`` on ``/v1/stream`` to
  receiving its first 30-frame chunk, best of ``repeats`` (the session already open);
- ``ws_char_frames_per_s``: the same stream to its ``end``, acking every chunk;
- ``live_characters_30fps``: null -- live mode is not built yet;
- ``bytes_per_joint_frame``: s48, measured on the answer.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import msgpack
import numpy as np

from api_schemas.wire import blob
from synth_core import crowd

CHARACTERS, FRAMES = 500, 500


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


def rest(url: str, body: dict[str, Any], repeats: int) -> tuple[float, bytes]:
    raw = msgpack.packb(body, use_bin_type=True)
    best, content = float("inf"), b""
    with httpx.Client(base_url=url, timeout=300) as client:
        for _ in range(repeats):
            t0 = time.perf_counter()
            response = client.post("/v1/synthesize", content=raw,
                                   headers={"content-type": "application/vnd.msgpack"})
            best = min(best, time.perf_counter() - t0)
            response.raise_for_status()
            content = response.content
    return best, content


def stream(url: str, body: dict[str, Any], repeats: int) -> tuple[float, float]:
    """Best seconds to the first chunk and to the end."""
    from websockets.sync.client import connect

    raw = msgpack.packb({"type": "synthesize", "chunk_frames": 30, **body}, use_bin_type=True)
    first, whole = float("inf"), float("inf")
    with connect(url.replace("http://", "ws://") + "/v1/stream", compression=None, max_size=None) as ws:
        for _ in range(repeats):
            t0 = time.perf_counter()
            ws.send(raw)
            while True:
                message = msgpack.unpackb(ws.recv(timeout=300))
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


def run(url: str | None = None, repeats: int = 4) -> dict[str, Any]:
    if url is None:
        with local_service() as local:
            return run(local, repeats)
    paths = crowd.simulate(CHARACTERS, FRAMES, seed=0).astype(np.float32)
    body = {"seed": 1, "encoding": "s48",
            "characters": [{"id": f"h{c}", "points": blob(p)} for c, p in enumerate(paths)]}
    seconds, content = rest(url, body, repeats)
    answer = msgpack.unpackb(content)
    frames = answer["characters"][0]["frames"]
    rotations = answer["characters"][0]["rotations"]
    joints = rotations["shape"][1]
    first, whole = stream(url, body, repeats)
    return {"rest_char_frames_per_s": round(CHARACTERS * FRAMES / seconds),
            "ws_first_chunk_ms": round(first * 1e3, 1),
            "ws_char_frames_per_s": round(CHARACTERS * FRAMES / whole),
            "live_characters_30fps": None,
            "bytes_per_joint_frame": len(rotations["data"]) / (frames * joints),
            "rest_seconds": round(seconds, 3), "response_bytes": len(content)}
