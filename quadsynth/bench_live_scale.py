"""The live benchmark at scale (issue 31): per encoding and level-of-detail mix, the largest herd
a service holds at 30 fps, and the bytes per second on the wire carrying it. Part of
``quadsynth bench-service --json`` (``live_scale``); alone: ``--live-scale``.

A herd is cut into sessions of SESSION_CHARACTERS (a game server sharding its herd over
connections; one session of 100,000 would exceed the service's default limits: max_characters
10,000, and a tick of points, 18 MB, its 8 MB message limit), all started together, each fed
half-second ticks of 30 fps crowd-simulation points (:func:`quadsynth.bench_service.live`).

For each configuration:

1. ``capacity``: the herd fed as fast as the service takes it (unpaced): characters x simulated
   seconds / wall seconds -- the characters it would keep at 30 fps if the cost is linear;
2. ``held``: then a herd of 90% of the capacity (or the target, if between that and the
   capacity) fed in real time; held if no frame's pose came later than the session's
   documented latency plus two ticks (a second: a frame settles only when the tick bringing
   its look-ahead's last point arrives, then takes the making and sending of a tick): a service
   falling behind piles up lag tick by tick (at 90% of the pace, a second in 10 s). Else
   retried once at 75%.

``wire_MB_s``: the chunks' bytes (whole WebSocket messages: root, gait, contacts and msgpack
included) per character-frame, times 30 and the herd held. The client (this process) shares
the service's cores: its reading is part of what limits the herd on one machine.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import httpx
import numpy as np

from quadsynth.bench_service import LIVE_TICK, MIXES, live
from synth_core.quality import herd_sim as crowd

SESSION_CHARACTERS = 5000  # its 21 ticks of points (19 MB) fit the service's live inbox (32 MB)
SECONDS = 10.0
LINK_MB_S = 125.0  # a 1 Gbit/s link
# (encoding, mix, target herd): the targets -- 100,000 at a realistic mix (a tenth at
# full detail, the rest root, gait and contacts only), 50,000 at full detail with foot lock.
CONFIGS: tuple[tuple[str, str, int], ...] = (
    ("delta", "tenth_full_rest_root_gait", 100_000),
    ("delta", "full", 50_000),
    ("s48", "full", 50_000),
)


def sessions(total: int, size: int) -> list[int]:
    """``total`` characters cut into sessions of at most ``size``."""
    n = -(-total // size)
    return [total // n + (1 if i < total % n else 0) for i in range(n)]


def herd(url: str, total: int, encoding: str, mix: str, paths: np.ndarray, paced: bool,
         size: int = SESSION_CHARACTERS) -> dict[str, float]:
    """``total`` characters in sessions side by side: (characters at 30 fps, worst pose lag,
    bytes and frames on the wire, the session's latency)."""
    counts = sessions(total, size)
    start = threading.Barrier(len(counts), timeout=300)  # a session failing to start breaks it
    wires: list[dict[str, float]] = [{} for _ in counts]

    def one(i: int, C: int) -> tuple[float, float]:
        options: dict[str, Any] = {"encoding": encoding, "seed": 1 + i, **MIXES[mix](C)}
        return live(url, C, SECONDS, paced, options, wires[i], paths[:C], start.wait)

    with ThreadPoolExecutor(len(counts)) as pool:
        results = list(pool.map(lambda a: one(*a), enumerate(counts)))
    # Each session's rate is its characters x simulated s / its wall s: together, the slowest's.
    wall_ratio = min(rate / C for (rate, _), C in zip(results, counts, strict=True))
    char_frames = sum(w["frames"] * C for w, C in zip(wires, counts, strict=True))
    return {"characters_30fps": total * wall_ratio, "lag_s_max": max(lag for _, lag in results),
            "bytes": sum(w["bytes"] for w in wires), "char_frames": char_frames,
            "latency_s": max(w["latency_s"] for w in wires)}


def configuration(url: str, encoding: str, mix: str, target: int, paths: np.ndarray,
                  log: Callable[[str], None]) -> dict[str, Any]:
    probe = herd(url, target, encoding, mix, paths, paced=False)
    capacity = probe["characters_30fps"]
    log(f"live-scale {encoding}/{mix}: {target:,} unpaced -> capacity {capacity:,.0f} at 30 fps")
    tries = []
    # 90% of the capacity (the largest herd it may hold) -- or the target, if that is between.
    size = target if 0.9 * capacity < target <= capacity else int(0.9 * capacity) // 100 * 100
    for _ in range(2):
        if size < 100:
            break
        run = herd(url, size, encoding, mix, paths, paced=True)
        held = run["lag_s_max"] <= run["latency_s"] + 2 * LIVE_TICK / 30
        tries.append({"characters": size, "held": held, "lag_s_max": round(run["lag_s_max"], 3),
                      "latency_s": round(run["latency_s"], 3)})
        log(f"live-scale {encoding}/{mix}: {size:,} paced -> lag {run['lag_s_max']:.2f} s "
            f"(latency {run['latency_s']:.2f} s): {'held' if held else 'not held'}")
        if held:
            break
        size = int(0.75 * size) // 100 * 100
    held_size = next((t["characters"] for t in tries if t["held"]), 0)
    per_char_frame = probe["bytes"] / probe["char_frames"]
    wire = per_char_frame * 30 * held_size / 1e6
    out: dict[str, Any] = {
        "target": target, "capacity_30fps": round(capacity), "characters_held_30fps": held_size,
        "paced_runs": tries, "wire_bytes_per_char_frame": round(per_char_frame, 1),
        "wire_MB_s_held": round(wire, 1),
        "wire_MB_s_at_target": round(per_char_frame * 30 * target / 1e6, 1),
        "meets_target": held_size >= target}
    if encoding == "delta":
        out["meets_link"] = per_char_frame * 30 * target / 1e6 <= LINK_MB_S
    return out


def live_scale(url: str, configs: tuple[tuple[str, str, int], ...] = CONFIGS,
               log: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """Every configuration's figures (``"encoding/mix"``), in one run."""
    with httpx.Client(base_url=url, timeout=60) as client:
        limit = int(client.get("/v1/limits").json()["max_characters"])
    assert limit >= SESSION_CHARACTERS, f"the service takes at most {limit} characters a session"
    paths = crowd.simulate(SESSION_CHARACTERS, int(SECONDS * 30) + 1, seed=0, fps=30.0).astype(np.float32)
    return {f"{enc}/{mix}": configuration(url, enc, mix, target, paths, log) for enc, mix, target in configs}
