"""Run-time synthesis benchmark on the built-in horse and crowd-sim herds. Prints one JSON object.

    python -m bench.bench_synth [--quick]

End to end: trajectories in, local rotations + root out, foot lock included (the bank, built
once per library at service start, is not timed). ``scaling``: characters at 500 frames and
frames at 500 characters (``--quick`` stops at 1,000 characters / 1,000 frames). Not a test.
"""

from __future__ import annotations

import argparse
import json
import time

from synth_core import crowd
from synth_core.bank import build_bank
from synth_core.build import build_builtin
from synth_core.synthesis import Options, synthesize


def timed(bank, characters: int, frames: int, foot_lock: bool = True) -> float:  # type: ignore[no-untyped-def]
    paths = crowd.simulate(characters, frames, seed=0, top=6.0)
    t0 = time.perf_counter()
    synthesize(bank, paths, options=Options(scale_range=(0.8, 1.2), seed=0, foot_lock=foot_lock))
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    bank = build_bank(build_builtin("horse"))
    timed(bank, 10, 100)  # warm up
    main_s = timed(bank, 500, 500)
    no_lock_s = timed(bank, 500, 500, foot_lock=False)
    chars = [10, 100, 1000] if args.quick else [10, 100, 1000, 10000]
    frames = [100, 500, 1000] if args.quick else [100, 500, 1000, 2000]
    scaling = [{"characters": c, "frames": 500, "seconds": round(timed(bank, c, 500), 3)} for c in chars]
    scaling += [{"characters": 500, "frames": f, "seconds": round(timed(bank, 500, f), 3)} for f in frames]
    rate = 500 * 500 / main_s
    print(json.dumps({
        "char_frames_per_s": round(rate),
        "char_frames_per_s_without_foot_lock": round(500 * 500 / no_lock_s),
        "scaling": scaling,
        "realtime_characters_30fps": int(rate / 30),
    }, indent=2))


if __name__ == "__main__":
    main()
