"""A scenario played through a live session (:class:`synth_core.runtime.live.LiveSynth`) fed tick
by tick, as a simulator would: the frames it sends joined into a :class:`Result` the edge
figures read, and how far behind the points each tick's last frame sent was.

The honest measure of a live mode: its motion is what a client receives, not a batch's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core.runtime.bank import Bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.streaming import Window
from synth_core.runtime.synthesis import Result
from synth_core.runtime.terrain import HeightField


@dataclass(frozen=True)
class LiveRun:
    """A live session's output as a :class:`Result`, and per tick (after its points) the library
    frames between the last point received and the last frame sent (``lags``)."""

    result: Result
    lags: NDArray[np.int64]
    latency_frames: int  # the session's bound on them


# A session's options and what the simulator sends, each its own argument (as LiveSynth's).
def play(bank: Bank, positions: NDArray[np.floating], scales: NDArray[np.floating] | None = None,  # noqa: PLR0913
         seed: int = 0, latency_ms: float | None = None, ground: HeightField | None = None, *,
         points_per_tick: int = 1, backend: str = "auto",
         velocity: NDArray[np.floating] | None = None) -> LiveRun:
    """``positions (C, T, 3)`` at the library's fps, ``points_per_tick`` points a tick, then
    finish; ``latency_ms``: the low-latency mode's budget (None: the exact mode); ``velocity
    (C, T, 2)``: sent with the points, if given (the simulator's ground velocity, m/s)."""
    C, T = positions.shape[:2]
    live = LiveSynth(bank, C, bank.fps, scales=scales, seed=seed, backend=backend, ground=ground,
                     latency_ms=latency_ms)
    windows: list[Window] = []
    lags = np.empty(-(-T // points_per_tick), np.int64)
    for k, i in enumerate(range(0, T, points_per_tick)):
        window = live.append(positions[:, i:i + points_per_tick], None,
                             None if velocity is None else velocity[:, i:i + points_per_tick])
        if window is not None:
            windows.append(window)
        lags[k] = min(i + points_per_tick, T) - live.rendered
    last = live.finish()
    if last is not None:
        windows.append(last)

    def cat(field: str) -> NDArray[np.generic]:
        return np.concatenate([getattr(w, field) for w in windows], axis=1)

    root = cat("root_pos")
    n = root.shape[1]
    # The path followed: the points themselves (a live session keeps no smoothed path; the edge
    # figures read its height as the ground under the feet, and the points carry it).
    path = np.asarray(positions[:, :n], np.float64)
    result = Result(root.astype(np.float32), cat("rotations").astype(np.float32),
                    cat("gait").astype(np.int8), cat("contacts").astype(bool), np.zeros((C, n), bool),
                    live.scales, path, 1.0, np.arange(C), mirrored=live.leads > 0)
    return LiveRun(result, lags, live.latency_frames)
