"""What far characters cost, in process: one herd fed 10 s of 30 fps points in half-second ticks
to a live session, and the same herd as one batch (``synthesize``: a REST answer's or a WebSocket
batch's work), with every character posed (full detail), none (all at root_gait: root, gait and
contacts only) and one in ten, in the same run. Prints one JSON object: seconds each (best of
``--repeats``) and each against full, the batch's under ``batch_``. Not a test.

    python -m bench.bench_live_lod [--characters 2000] [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

import numpy as np

from synth_core.build.animals import build_builtin
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.synthesis import Options, synthesize

SECONDS, TICK = 10.0, 15


def session(bank: Bank, paths: np.ndarray, pose: np.ndarray) -> float:
    live = LiveShards(bank, len(paths), 30.0, seed=1, reuse_windows=True)
    live.set_posed(pose)
    t0 = time.perf_counter()
    for i in range(0, paths.shape[1], TICK):
        live.append(paths[:, i:i + TICK], live.window_frames)
        while live.take(live.window_frames) is not None:
            pass
    while live.finish(live.window_frames) is not None:
        pass
    return time.perf_counter() - t0


def batch(bank: Bank, paths: np.ndarray, pose: np.ndarray) -> float:
    t0 = time.perf_counter()
    synthesize(bank, paths, fps=30.0, options=Options(seed=1, posed=pose))
    return time.perf_counter() - t0


def timed(bank: Bank, paths: np.ndarray, mixes: dict[str, np.ndarray], repeats: int,
          one: Callable[[Bank, np.ndarray, np.ndarray], float], prefix: str) -> dict[str, float]:
    """Each mix's best time and its share of full's."""
    best = {name: min(one(bank, paths, pose) for _ in range(repeats)) for name, pose in mixes.items()}
    out = {f"{prefix}{name}_s": round(s, 3) for name, s in best.items()}
    return out | {f"{prefix}{name}_vs_full": round(s / best["full"], 3)
                  for name, s in best.items() if name != "full"}


def run(characters: int, repeats: int) -> dict[str, float]:
    bank = build_bank(build_builtin("horse"))
    paths = crowd.simulate(characters, int(SECONDS * 30) + 1, seed=0, fps=30.0)
    C = characters
    mixes = {"full": np.ones(C, bool), "all_root_gait": np.zeros(C, bool),
             "tenth_full_rest_root_gait": np.arange(C) % 10 == 0}
    session(bank, paths[:min(C, 200)], mixes["full"][:min(C, 200)])  # compiled, pages touched
    batch(bank, paths[:min(C, 200)], mixes["full"][:min(C, 200)])
    live = timed(bank, paths, mixes, repeats, session, "")
    whole = timed(bank, paths, mixes, repeats, batch, "batch_")
    return live | whole | {"characters": C, "simulated_s": SECONDS}


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--characters", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    print(json.dumps(run(args.characters, args.repeats)))
