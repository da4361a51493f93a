"""Pose latency of a live session per mode (issue 31), for ``quadsynth bench-service``: a herd
fed one 30 fps point per tick in real time, as a game's simulation sends them; each frame's
latency is from sending its point to receiving the chunk holding its pose. Reports p50, p99 and
the largest, in ms, per mode (exact: the batch's frames; low_latency: the profile's budget).
"""

from __future__ import annotations

import time
from typing import Any

import msgpack
import numpy as np

from api_schemas.wire import blob
from quadsynth.bench_ws import LeanSocket
from synth_core.quality import herd_sim as crowd

LATENCY_CHARACTERS, LATENCY_SECONDS = 200, 8.0  # short: the figure is per frame, not per herd
MODES: dict[str, dict[str, Any]] = {"exact": {}, "low_latency": {"mode": "low_latency"}}


def paced_latency(url: str, options: dict[str, Any], characters: int = LATENCY_CHARACTERS,
                  seconds: float = LATENCY_SECONDS) -> dict[str, Any]:
    """A live session with the live message's ``options``, a point a tick at 30 fps, then
    finish: per frame sent before the finish, the ms from its point's send to its pose's arrival."""
    F = int(seconds * 30)
    paths = crowd.simulate(characters, F, seed=0, fps=30.0).astype(np.float32)
    ticks = [msgpack.packb({"type": "points", "points": blob(np.ascontiguousarray(paths[:, i:i + 1]))},
                           use_bin_type=True) for i in range(F)]
    opening = {"type": "live", "fps": 30, "seed": 1, "encoding": "s48",
               "characters": [{"id": f"h{c}"} for c in range(characters)], **options}
    sent_at = np.full(F, np.nan)
    got_at = np.full(F, np.nan)
    frames = 0
    with LeanSocket(url.replace("http://", "ws://") + "/v1/stream") as ws:
        ws.send(msgpack.packb(opening, use_bin_type=True))
        header = ws.recv_head()
        if header["type"] != "start":
            raise SystemExit(f"bench-service: the live session failed: {header}")
        t0, sent = time.perf_counter(), 0
        while True:
            if sent < F and time.perf_counter() >= t0 + sent / 30:
                ws.send(ticks[sent])
                sent_at[sent] = time.perf_counter()
                sent += 1
                if sent == F:
                    ws.send(msgpack.packb({"type": "finish"}))
                continue
            try:
                message = ws.recv_head(timeout=max(t0 + sent / 30 - time.perf_counter(), 0.001)
                                       if sent < F else None)
            except TimeoutError:
                continue
            if message["type"] == "chunk":
                n = message["frames"]
                got_at[frames:frames + n] = time.perf_counter()
                frames += n
                ws.send(msgpack.packb({"type": "ack", "chunk": message["chunk"]}))
            elif message["type"] == "end":
                break
            else:
                raise SystemExit(f"bench-service: the live session failed: {message}")
    # Frames sent before the finish: those the mode's latency holds for (the finish flushes the rest).
    before = got_at < sent_at[-1]
    ms = (got_at - sent_at)[before] * 1e3
    if not ms.size:
        return {"latency_frames": header["latency_frames"], "frames_before_finish": 0}
    return {"latency_frames": header["latency_frames"], "latency_s_bound": round(header["latency_s"], 3),
            "latency_ms_p50": round(float(np.percentile(ms, 50)), 1),
            "latency_ms_p99": round(float(np.percentile(ms, 99)), 1),
            "latency_ms_max": round(float(ms.max()), 1), "frames_before_finish": int(ms.size),
            "characters": characters}


def per_mode(url: str) -> dict[str, Any]:
    """:func:`paced_latency` of every mode of :data:`MODES`."""
    return {name: paced_latency(url, options) for name, options in MODES.items()}
