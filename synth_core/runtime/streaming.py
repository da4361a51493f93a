"""A batch synthesized in time windows: its first frames come out long before its last are made,
and every frame is the number :func:`synth_core.runtime.synthesis.synthesize` gives for the whole batch.

Why the windows can be exact:

- the plan of the first frames is the whole plan's (:func:`synth_core.runtime.plan.plan` with
  ``frames``; draws are per character and per decision, :mod:`synth_core.runtime.draws`), so the first
  window waits only for its own frames' plan; the rest use the whole plan, made meanwhile;
- a frame's pose is its plan row's, but the foot lock looks further: a planted foot goes to its
  plant's average position, a swinging one eases between the plants either side, and the root's
  sink is eased over ``PAD`` frames either side. So each character renders a window over a
  *context* -- from the start of the plant (or the plant before the swing) ``PAD`` frames before
  the window, to the end of the plant (or the plant after the swing) ``PAD`` frames after it --
  and keeps the window's frames. Within the context every plant that matters is whole, so the
  numbers are the same (tested bit for bit).

The context costs extra frames (a stride or two either side), so after the first window the
frames are rendered ``RENDER_CHUNKS`` chunks at a time.

The first window is what a client waits for. Its plan and render are small calls the compiled
kernels hardly speed up on more threads (500 horses: 1.2-1.3x on two), so its characters are
cut into parts planned and rendered side by side on :mod:`synth_core.compiled.render_pool`, each with a
one-thread kernel (characters are independent: the same numbers, tested).
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core.compiled import kernels, render_pool
from synth_core.runtime.bank import Bank
from synth_core.runtime.footlock import PAD
from synth_core.runtime.synthesis import Options, Plan, compiled_backend, plan, prepare_batch
from synth_core.runtime.terrain import along_ground, ground_plan

RENDER_CHUNKS = 4  # chunks rendered at once after the first (the context's cost spread over more)
# The first window's plan reaches this many mean cycles past its lock's pad, then (if a plant runs
# past that) the next, then the whole. With the horse's gaits at the literature's tempo (mean
# cycle 42 frames, was 57) its crowd's start-up plants end ~1.6 cycles past it: so 2 first; a
# slow walk's run to ~5; a standing animal's not before the batch does.
FIRST_PLAN_STRIDES = (2.0, 5.5)
MIN_PART = 32  # characters: a first window's part no smaller (a thread hop costs ~0.1 ms)


@dataclass(frozen=True, eq=False)
class Window:
    """Frames ``[start, start + n)`` of every kept character."""

    start: int
    root_pos: NDArray[np.float32]  # (C, n, 3)
    rotations: NDArray[np.float32]  # (C, n, J, 4)
    gait: NDArray[np.int8]  # (C, n)
    contacts: NDArray[np.bool_]  # (C, n, 4)

    @property
    def stop(self) -> int:
        return self.start + int(self.root_pos.shape[1])


@dataclass(eq=False)
class BatchStream:
    """A batch checked and prepared (as :func:`synthesize` does: errors are raised here), whose
    motion :meth:`windows` then makes ``chunk_frames`` frames at a time."""

    bank: Bank
    positions: ArrayLike
    fps: float | None = None
    scales: ArrayLike | None = None
    options: Options = Options()
    ids: list[str] | None = None
    seeds: ArrayLike | None = None
    chunk_frames: int = 30
    _plan: Plan | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.chunk_frames, int) and self.chunk_frames >= 1):
            raise ValueError(f"chunk_frames: must be a positive integer, got {self.chunk_frames!r}")
        self.prep, self.character_scales, self.keys = prepare_batch(
            self.bank, self.positions, self.fps, self.scales, self.options, self.ids, self.seeds)
        if self.options.ground is not None:
            self.prep = along_ground(self.prep, self.options.ground, self.bank.fps)
        self.frames = self.prep.positions.shape[1]

    @property
    def kept(self) -> NDArray[np.int64]:
        return self.prep.kept

    @property
    def rejected(self) -> dict[int, str]:
        return self.prep.rejected

    @property
    def warnings(self) -> dict[int, str]:
        return self.prep.warnings

    @property
    def resample_rate(self) -> float:
        return self.prep.resample_rate

    def _whole_plan(self) -> Plan:
        if self._plan is None:
            self._plan = plan(self.bank, self.prep, self.character_scales, self.keys, self.options.margin,
                              compiled=compiled_backend(self.options))
        return self._plan

    def _context(self, p: Plan, start: int, stop: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        return kernels.lock_context(p.contacts, start, stop, compiled_backend(self.options))

    def _render(self, p: Plan, start: int, stop: int,
                context: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None,
                shared: bool = False, rows: slice = slice(None)) -> Window:
        """Frames ``[start, stop)`` of plan ``p`` (``context``: their lock contexts, if known;
        ``shared``: in parts the pool's idle threads may take, see kernels.render_window;
        ``rows``: the characters ``p`` plans, of the prepared batch's)."""
        lock = self.options.foot_lock
        C = p.yaw.shape[0]
        if not lock:
            begin, end = np.full(C, start), np.full(C, stop)
        else:
            begin, end = self._context(p, start, stop) if context is None else context
        gait = p.gait[:, start:stop]
        contacts = np.empty((C, stop - start, 4), np.bool_)  # the feet planted as posed (kernels.render)
        at, ground = start, None
        if self.options.ground is not None:  # the frames read, on the terrain (terrain.ground_plan)
            o = int(begin.min())
            p, ground = ground_plan(self.bank, p.window(o, int(end.max())), self.options.ground)
            start, stop, begin, end = start - o, stop - o, begin - o, end - o
        root, rot = kernels.render_window(self.bank, p, start, stop, begin, end, lock,
                                          share=render_pool.shared if shared else None, ground=ground,
                                          pose=self.options.posed_rows(self.prep.kept[rows]),
                                          compiled=compiled_backend(self.options), contacts=contacts)
        return Window(at, root, rot, gait, contacts)

    def _first_part(self, rows: slice, stop: int, shared: bool = False) -> tuple[Window, Plan | None]:
        """Frames ``[0, stop)`` of characters ``rows``, from a plan of just those frames and
        their lock context's if that is enough; and the part's whole plan if it took it.
        ``shared``: one of parts side by side on the pool, whose renders the part done first
        helps finish (the parts' plans and contexts differ: one ended up to 5 ms after the other)."""
        prep = self.prep.rows(rows)
        h, keys = self.character_scales[rows], self.keys[rows]
        compiled, T = compiled_backend(self.options), self.frames
        margin, lock = self.options.margin, self.options.foot_lock
        for strides in FIRST_PLAN_STRIDES:
            reach = stop + PAD + int(strides * self.bank.mean_cycle)
            early = plan(self.bank, prep, h, keys, margin, frames=reach, compiled=compiled)
            if early.yaw.shape[1] == T:  # that was all of it
                return self._render(early, 0, stop, shared=shared, rows=rows), early
            context = self._context(early, 0, stop) if lock else None
            if context is None or context[1].max() < early.yaw.shape[1]:
                return self._render(early, 0, stop, context, shared, rows), None
        whole = plan(self.bank, prep, h, keys, margin, compiled=compiled)  # a plant runs past them all
        return self._render(whole, 0, stop, shared=shared, rows=rows), whole

    def _first_window(self, stop: int) -> list[Window]:
        """Frames ``[0, stop)``: the characters in parts side by side (see the module doc), a
        window per part."""
        C = self.prep.positions.shape[0]
        parts = min(render_pool.size(), C // MIN_PART) if compiled_backend(self.options) else 1
        if parts <= 1:
            window, whole = self._first_part(slice(0, C), stop)
            self._plan = whole if whole is not None else self._plan
            return [window]
        cuts = np.linspace(0, C, parts + 1).round().astype(np.int64).tolist()
        done = render_pool.side_by_side([functools.partial(self._first_part, slice(a, b), stop, True)
                                         for a, b in zip(cuts[:-1], cuts[1:], strict=True)])
        plans = [whole for _, whole in done]
        if all(p is not None for p in plans):  # every part planned whole: that is the whole plan
            self._plan = Plan(*(np.concatenate([getattr(p, f.name) for p in plans]) for f in fields(Plan)))
        return [w for w, _ in done]

    def windows(self) -> Iterator[Window]:
        """The motion, ``chunk_frames`` frames at a time, in order."""
        for chunk in self.chunks():
            yield joined(chunk)

    def chunks(self) -> Iterator[list[Window]]:
        """:meth:`windows`, each as the windows of consecutive characters it was made in: the
        first in its parts, the others whole. The service packs a chunk's windows side by side
        (:func:`service.chunk.packed_chunk`): joined first, the first chunk was packed on one
        thread, ~2 ms of the ~40-50 a client waits for it."""
        K, T = self.chunk_frames, self.frames
        first_stop = min(K, T)
        yield self._first_window(first_stop)
        if first_stop == T:
            return
        whole = self._whole_plan()
        for a in range(first_stop, T, K * RENDER_CHUNKS):
            b = min(a + K * RENDER_CHUNKS, T)
            w = self._render(whole, a, b)
            for s in range(a, b, K):
                n = slice(s - a, min(s + K, b) - a)
                yield [Window(s, w.root_pos[:, n], w.rotations[:, n], w.gait[:, n], w.contacts[:, n])]


def joined(windows: list[Window]) -> Window:
    """Windows of the same frames of consecutive characters as one window of them all."""
    if len(windows) == 1:
        return windows[0]
    return Window(windows[0].start, *(np.concatenate([getattr(w, f) for w in windows])
                                      for f in ("root_pos", "rotations", "gait", "contacts")))
