"""``quadsynth bench``: synthesis speed on the built-in horse with crowd-sim herds (one JSON object).

End to end: trajectories in, local rotations + root out, foot lock included; the bank (built
once per library when the service starts) and the kernels' first compilation are not timed.
``scaling``: characters 10 -> 10,000 at 500 frames and frames 100 -> 2,000 at 500 characters;
each point is the best of ``repeats`` runs (this is a shared 2-core machine: the best run is the
machine's speed, the others its neighbours'), writing into the output arrays of a first, untimed
run (see :func:`timed`). Each point's ``char_frames_per_s`` counts the frames synthesized
(``frames_out``: more than ``frames`` where the herd is resampled); ``scaling_cost_spread``: the
largest over the smallest of them along each axis (linear scaling: 1.0). The on-the-fly
baseline runs once, on 100 x 500.
"""

from __future__ import annotations

import time
from typing import Any

from synth_core import crowd
from synth_core.bank import Bank, build_bank
from synth_core.build import build_builtin
from synth_core.onthefly import synthesize_onthefly
from synth_core.synthesis import Options, synthesize

OPTIONS = Options(scale_range=(0.8, 1.2), seed=0)
SHORT_POINT_S = 2.0  # a point's runs take about this long at least
MAX_REPEATS = 40


def timed(bank: Bank, characters: int, frames: int, repeats: int = 3) -> tuple[float, int]:
    """Best of ``repeats`` runs (more for a short point: as many as fit in ``SHORT_POINT_S``, up
    to ``MAX_REPEATS``) after a first one whose output arrays the runs then write into, as a
    simulator synthesizing batch after batch keeps its buffers: on this VM fresh memory costs
    up to 1.8 ms/MB on first touch, which would be most of the 10,000-character point.
    Returns the seconds and the frames synthesized per character (more than ``frames`` where
    a character is too fast for the library and the batch is resampled)."""
    paths = crowd.simulate(characters, frames, seed=0)
    t0 = time.perf_counter()
    first = synthesize(bank, paths, options=OPTIONS)
    once = time.perf_counter() - t0
    out = (first.root_pos, first.rotations)
    # A neighbour on this shared machine can take a core for a second; a 5 ms point then needs
    # many runs for one undisturbed one.
    repeats = max(repeats, min(MAX_REPEATS, int(SHORT_POINT_S / max(once, 1e-3))))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        synthesize(bank, paths, options=OPTIONS, out=out)
        best = min(best, time.perf_counter() - t0)
    return best, int(first.root_pos.shape[1])


def run(quick: bool = False) -> dict[str, Any]:
    library = build_builtin("horse")
    bank = build_bank(library)
    synthesize(bank, crowd.simulate(10, 100, seed=0), options=OPTIONS)  # compile / load the kernels
    main_s, _ = timed(bank, 500, 500, repeats=5)
    rate = 500 * 500 / main_s
    paths = crowd.simulate(100, 500, seed=0)
    t0 = time.perf_counter()
    synthesize_onthefly(bank, library, paths, options=OPTIONS)
    onthefly = 100 * 500 / (time.perf_counter() - t0)
    chars = [10, 100, 1000] if quick else [10, 100, 1000, 10000]
    frames = [100, 500, 1000] if quick else [100, 500, 1000, 2000]
    scaling = []
    for c, f in [(c, 500) for c in chars] + [(500, f) for f in frames]:
        seconds, out_frames = timed(bank, c, f, 3)
        # Per frame synthesized: a herd with a character too fast for the library is resampled
        # (crowd-sim's 2,000-frame herd: 2,115 frames), and those frames are made too.
        scaling.append({"characters": c, "frames": f, "seconds": round(seconds, 4), "frames_out": out_frames,
                        "char_frames_per_s": round(c * out_frames / seconds)})
    spread = {}
    for axis, points in (("characters", scaling[:len(chars)]), ("frames", scaling[len(chars):])):
        speeds = [p["char_frames_per_s"] for p in points]
        spread[axis] = round(max(speeds) / min(speeds), 2)  # cost per character-frame, max / min
    return {
        "char_frames_per_s": round(rate),
        "onthefly_char_frames_per_s": round(onthefly),
        "speedup_vs_onthefly": round(rate / onthefly, 1),
        "scaling": scaling,
        "scaling_cost_spread": spread,
        "realtime_characters_30fps": int(rate / 30),
    }
