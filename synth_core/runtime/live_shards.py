"""A live session's characters cut into shards, each a :class:`LiveSynth`, advanced together on
every core.

Most of a live tick is numpy on (characters, frames) arrays -- smoothing, speeds, headings,
the plan's bookkeeping -- which runs on one core while the other waits for the render kernel's
parallel part. Every character's frames depend on its own points and its own draws only (its key
is :func:`synth_core.runtime.draws.character_keys` of its index in the session: a shard is told its
first), so shards of characters, each advanced in its own thread with a one-thread render,
make the same frames bit for bit (tested) while their numpy and kernels run side by side
(both release the GIL). 4,000 horses fed 10 s at 30 fps, in-process: 2.2-3.0 -> 1.7-2.1 s.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core.compiled import render_pool
from synth_core.runtime.bank import Bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.streaming import Window
from synth_core.runtime.terrain import HeightField
from synth_core.runtime.trajectory import TrajectoryError

MIN_SHARD = 500  # characters: below this a shard's thread hops cost more than they save
_R = TypeVar("_R")


def shard_bounds(n_characters: int, shards: int | None = None) -> NDArray[np.int64]:
    """``shards + 1`` cuts of ``[0, n_characters)`` into near-equal shards: by default one per
    core, each at least MIN_SHARD characters (one shard for fewer)."""
    if shards is None:
        shards = min(render_pool.size(), n_characters // MIN_SHARD)
    shards = max(1, min(shards, n_characters))
    return np.linspace(0, n_characters, shards + 1).round().astype(np.int64)


class LiveShards:
    """:class:`LiveSynth`'s interface for a session of ``n_characters`` (same arguments), its
    characters in shards: :meth:`append` and :meth:`finish` give one :class:`Window` per
    shard, characters in order (:func:`synth_core.runtime.streaming.joined` makes them one)."""

    def __init__(self, bank: Bank, n_characters: int, fps: float | None = None, *,
                 scales: ArrayLike | None = None, seeds: ArrayLike | None = None,
                 shards: int | None = None, **options: Any) -> None:
        if not (isinstance(n_characters, int) and n_characters >= 1):
            raise TrajectoryError(f"characters: need at least one, got {n_characters}")
        self.cuts = shard_bounds(n_characters, shards)

        def each(name: str, values: ArrayLike | None, dtype: type) -> list[NDArray[Any] | None]:
            if values is None:
                return [None] * (len(self.cuts) - 1)
            arr: NDArray[Any] = np.asarray(values, dtype)
            if arr.shape != (n_characters,):
                raise TrajectoryError(f"{name}: expected {n_characters} values (one per character), "
                                      f"got shape {arr.shape}")
            return [arr[a:b] for a, b in zip(self.cuts[:-1], self.cuts[1:], strict=True)]

        shard_scales, shard_seeds = each("scales", scales, np.float64), each("seeds", seeds, np.int64)
        # A shard done with its tick takes parts of another's render (the shards' characters pose
        # unequal work: in a herd sorted by rows, one half's took a tenth longer than the other's).
        options.setdefault("share_render", len(self.cuts) > 2)
        self.parts = [self._each_shard(functools.partial(LiveSynth, bank, int(b - a), fps, scales=sc,
                                                         seeds=sd, first=int(a), **options), int(a))
                      for a, b, sc, sd in zip(self.cuts[:-1], self.cuts[1:], shard_scales, shard_seeds,
                                              strict=True)]
        first = self.parts[0]
        self.latency_frames, self.out_step = first.latency_frames, first.out_step
        self.window_frames = first.window_frames
        self.scales = np.concatenate([p.scales for p in self.parts])
        self.n_characters = n_characters

    @staticmethod
    def _each_shard(work: Callable[[], _R], first: int) -> _R:
        """``work()`` for the shard whose first character is ``first``: its errors name the
        character by its index in the session."""
        try:
            return work()
        except TrajectoryError as exc:
            if exc.character is None or not isinstance(exc.character, int):
                raise
            raise TrajectoryError(exc.reason, exc.character + first) from None

    def _run(self, work: Callable[[int, LiveSynth], _R]) -> list[_R]:
        """``work(i, shard)`` for every shard, side by side (in the caller's thread for one)."""
        jobs = [functools.partial(self._each_shard, functools.partial(work, i, p), a)
                for i, (p, a) in enumerate(zip(self.parts, self.cuts[:-1].tolist(), strict=True))]
        if len(jobs) == 1:
            return [jobs[0]()]
        return render_pool.side_by_side(jobs)

    def append(self, points: ArrayLike, frames: int | None = None,
               velocity: ArrayLike | None = None) -> list[Window] | None:
        """:meth:`LiveSynth.append` for every shard: points ``(C, n, 3)`` (and their velocity
        ``(C, n, 2)``, if sent); nothing is taken unless every shard can take its characters'."""
        arr = np.asarray(points)
        C = self.n_characters
        if arr.ndim != 3 or arr.shape[0] != C or arr.shape[2] != 3 or arr.shape[1] < 1:
            raise TrajectoryError(f"points: expected shape ({C}, n >= 1, 3), got {arr.shape}")
        v = None if velocity is None else np.asarray(velocity)
        if v is not None and v.shape != (C, arr.shape[1], 2):
            raise TrajectoryError(f"velocity: expected shape ({C}, {arr.shape[1]}, 2) (x and z, m/s, of "
                                  f"every point sent), got {v.shape}")
        cuts = self.cuts.tolist()
        checked = [self._each_shard(functools.partial(part.check, arr[cuts[i]:cuts[i + 1]],
                                                      None if v is None else v[cuts[i]:cuts[i + 1]]), cuts[i])
                   for i, part in enumerate(self.parts)]  # all checked before any shard moves on
        return self._windows(self._run(lambda i, p: p.append_checked(checked[i], frames)))

    def finish(self, frames: int | None = None) -> list[Window] | None:
        """:meth:`LiveSynth.finish` for every shard."""
        return self._windows(self._run(lambda i, p: p.finish(frames)))

    def take(self, frames: int | None = None) -> list[Window] | None:
        """:meth:`LiveSynth.take` for every shard."""
        return self._windows(self._run(lambda i, p: p.take(frames)))

    def set_posed(self, pose: ArrayLike) -> None:
        """:meth:`LiveSynth.set_posed` for every shard: ``(C,)`` flags of the whole session."""
        arr = np.asarray(pose, bool)
        if arr.shape != (self.n_characters,):
            raise TrajectoryError(f"pose: expected {self.n_characters} flags (one per character), "
                                  f"got shape {arr.shape}")
        for part, a, b in zip(self.parts, self.cuts[:-1], self.cuts[1:], strict=True):
            part.set_posed(arr[a:b])

    @property
    def posed_frames(self) -> int:
        """Character-frames posed so far (see :meth:`LiveSynth.set_posed`)."""
        return sum(p.posed_frames for p in self.parts)

    def set_ground(self, ground: HeightField | None) -> None:
        """:meth:`LiveSynth.set_ground` for every shard (between steps: none is rendering)."""
        for part in self.parts:
            part.set_ground(ground)

    @staticmethod
    def _windows(windows: list[Window | None]) -> list[Window] | None:
        # The shards advance in step: all have frames or none.
        return None if windows[0] is None else [w for w in windows if w is not None]

