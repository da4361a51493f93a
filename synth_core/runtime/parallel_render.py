"""A prepared batch rendered in chunks side by side, the chunks' results handed out in order.

What an answer sent while it is made needs (``POST /v1/synthesize``): each chunk of characters
is planned and rendered on :mod:`synth_core.compiled.render_pool`'s threads (one core each), in
that thread's own :class:`Scratch` pages, and finished there too (the caller's ``finish``: e.g.
packed into the wire format), so the numpy around the render runs on every core as well; the
results come back in the chunks' order, a pool's worth ahead of the one taken.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from synth_core.compiled import render_pool
from synth_core.compiled.scratch import Scratch
from synth_core.runtime.bank import Bank
from synth_core.runtime.synthesis import Options, Rendered, render_chunk
from synth_core.runtime.trajectory import Prepared

_R = TypeVar("_R")


class Cancelled(Exception):
    """The caller asked the work to stop (its ``cancel`` event set): raised between chunks."""


_threads = threading.local()


def thread_scratch() -> Scratch:
    """This render thread's pages, kept from chunk to chunk and batch to batch."""
    kept = getattr(_threads, "scratch", None)
    if kept is None:
        kept = _threads.scratch = Scratch()
    return kept


def render_in_order(bank: Bank, prep: Prepared, h: NDArray[np.float64], keys: NDArray[np.uint64],
                    options: Options, per_chunk: int, finish: Callable[[Rendered, Scratch], _R],
                    cancel: threading.Event | None = None) -> Iterator[_R]:
    """``finish(chunk, scratch)`` of each chunk of ``per_chunk`` characters of a prepared batch
    (:func:`synth_core.runtime.synthesis.prepare_batch`), in order; the chunk's arrays live in
    ``scratch`` until that thread renders again, so ``finish`` copies what it keeps. Once
    ``cancel`` is set, :class:`Cancelled` at the next chunk; closed early, the chunks not begun
    are dropped and those running waited for."""
    def one(first: int) -> _R:
        if cancel is not None and cancel.is_set():
            raise Cancelled
        scratch = thread_scratch()
        rows = slice(first, min(first + per_chunk, prep.positions.shape[0]))
        return finish(render_chunk(bank, prep, h, keys, options, rows, scratch), scratch)

    for made in render_pool.ordered(one, range(0, prep.positions.shape[0], per_chunk)):
        if cancel is not None and cancel.is_set():
            raise Cancelled
        yield made
