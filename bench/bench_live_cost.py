"""What a live character costs, in CPU time per simulated second per 1,000 horses: far
(root_gait: not posed) and full characters of a live session (``LiveSynth``, one thread, fed
15 points a tick at 30 fps, every window taken), and the packing of the full ones' windows as
the service packs a chunk (``service.chunk.packed_chunk``: delta, s48). CPU time, not wall
time: robust to the machine's other load (docs/live_scale.md). The first ``WARM_S`` simulated
seconds (no frame is sent before the session's latency) are not counted. Prints one JSON
object, each figure the best of ``--repeats``. Not a test.

    python -m bench.bench_live_cost [--far 5000] [--full 1000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from api_schemas.wire import Encoding
from service import encode
from service.chunk import packed_chunk
from synth_core.build.animals import build_builtin
from synth_core.compiled import render_pool
from synth_core.compiled.scratch import Scratch
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.live import LiveSynth

TICK, FPS = 15, 30.0
SECONDS, WARM_S = 15.0, 5.0
ENCODINGS: tuple[Encoding, ...] = ("delta", "s48")


def session(bank: Bank, paths: np.ndarray, posed: bool, encodings: tuple[Encoding, ...]) -> dict[str, float]:
    """One session's CPU-s per simulated s per 1,000 characters: its synthesis and, per
    encoding, the packing of its windows."""
    C = len(paths)
    live = LiveSynth(bank, C, FPS, seed=1, reuse_windows=True)
    live.set_posed(np.full(C, posed))
    scratch = Scratch()
    packings = {e: encode.packing(e, 1, "full" if posed else "root_gait", [None] * C,
                                  bank.skeleton, live.scales) for e in encodings}
    cpu = dict.fromkeys(("synth", *encodings), 0.0)
    ticks = [np.ascontiguousarray(paths[:, i:i + TICK]) for i in range(0, paths.shape[1], TICK)]
    for k, points in enumerate(ticks):
        counted = k * TICK >= WARM_S * FPS
        t0 = time.process_time()
        windows = []
        window = live.append(points, live.window_frames)
        while window is not None:
            windows.append(window)
            window = live.take(live.window_frames)
        cpu["synth"] += (time.process_time() - t0) * counted
        for e in encodings:
            t0 = time.process_time()
            for w in windows:
                packed_chunk(1, k, [w], e, scratch, "chunk", packings[e])
            cpu[e] += (time.process_time() - t0) * counted
    per = (SECONDS - WARM_S) * C / 1000
    return {("synth" if name == "synth" else f"pack_{name}"): s / per for name, s in cpu.items()}


def run(far: int, full: int, repeats: int) -> dict[str, float]:
    bank = build_bank(build_builtin("horse"))
    paths = crowd.simulate(max(far, full), int(SECONDS * FPS) + 1, seed=0, fps=FPS).astype(np.float64)
    out: dict[str, float] = {}
    with render_pool.one_thread():
        session(bank, paths[:200], True, ENCODINGS)  # compiled, pages touched
        runs = [session(bank, paths[:far], False, ()) for _ in range(repeats)]
        out["far_synth"] = min(r["synth"] for r in runs)
        runs = [session(bank, paths[:full], True, ENCODINGS) for _ in range(repeats)]
        out |= {f"full_{k}": min(r[k] for r in runs) for k in runs[0]}
    return {k: round(v, 4) for k, v in out.items()} | {"far": far, "full": full}


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--far", type=int, default=5000)
    parser.add_argument("--full", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(json.dumps(run(args.far, args.full, args.repeats)))
