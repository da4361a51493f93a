"""A live session fed from the tests' side: points in random-sized pieces, its windows joined."""

from __future__ import annotations

import numpy as np

from synth_core.runtime.live import LiveSynth
from synth_core.runtime.streaming import Window


def feed(live: LiveSynth, positions: np.ndarray, seed: int = 0) -> tuple[list[Window], list[int]]:
    """Points in random-sized pieces, then finish; the windows, and after each piece how many
    library frames lag behind the points given."""
    rng = np.random.default_rng(seed)
    windows, lags = [], []
    i = 0
    while i < positions.shape[1]:
        n = int(rng.integers(1, 45))
        w = live.append(positions[:, i:i + n])
        i = min(i + n, positions.shape[1])
        if w is not None:
            windows.append(w)
        lags.append(round(i * live.bank.fps / live.fps) - live.rendered)
    last = live.finish()
    if last is not None:
        windows.append(last)
    return windows, lags


def joined(windows: list[Window]) -> tuple[np.ndarray, ...]:
    starts = [w.start for w in windows]
    assert starts == [0] + list(np.cumsum([w.stop - w.start for w in windows])[:-1])  # in order, no gap
    return tuple(np.concatenate([getattr(w, f) for w in windows], axis=1)
                 for f in ("root_pos", "rotations", "gait", "contacts"))
