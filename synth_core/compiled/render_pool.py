"""Threads that each run the compiled render on one core, for work cut into parts run side by
side: a live session's shards (:mod:`synth_core.runtime.live_shards`), a batch's chunks
(:func:`ordered`, used by :mod:`synth_core.runtime.parallel_render`).

Between render calls there is numpy on one core -- planning, packing -- while, with the render
fanned out to every core, the other cores wait for it. Parts of the work each in its own
thread, each with a one-thread render, keep every core busy with both (their numpy and
kernels release the GIL).
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from itertools import islice
from typing import TypeVar

from synth_core.compiled import kernels

_T = TypeVar("_T")
_R = TypeVar("_R")


def _one_render_thread() -> None:
    # With each kernel call fanning out to every core as well, two parts would run four
    # threads on two cores.
    if kernels.AVAILABLE:
        import numba

        numba.set_num_threads(1)  # per thread: other threads keep every core


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """The kernels called inside run on the calling thread alone (numba's setting is the
    thread's own), as before after.

    For work cut small, as a live tick's (a few frames of a session's characters): a kernel
    fanned out to every core ends by waiting for the slowest of its threads, and on a busy
    machine (other sessions, the service's packing, another process) that one waits for a
    scheduler slice at every kernel call: a live session fed a tick at a time ran ten times
    slower. Such work gets its cores from side-by-side parts instead: a session's shards, the
    service's sessions."""
    if not kernels.AVAILABLE:
        yield
        return
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


def size() -> int:
    """The pool's threads: one per core."""
    return os.cpu_count() or 1


@functools.cache
def pool() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(size(), thread_name_prefix="render", initializer=_one_render_thread)


def side_by_side(jobs: Sequence[Callable[[], _R]]) -> list[_R]:
    """Every job on the pool at once, their results in order; all ended before an error is
    raised (none left running)."""
    futures = [pool().submit(job) for job in jobs]
    wait(futures)
    return [f.result() for f in futures]


def shared(jobs: Sequence[Callable[[], object]]) -> None:
    """Run every job: the first in the caller's thread, the others offered to the pool -- a pool
    thread with nothing else to do takes one -- and those no thread has begun when the caller
    gets to them, the caller runs itself. The caller waits only for jobs already running, so a
    pool thread may call it; work of one thread spreads to those that are idle (a live session's
    shards: one has more to pose than the other). Errors are raised once all have ended."""
    offered = [pool().submit(job) for job in jobs[1:]]
    try:
        if jobs:
            jobs[0]()
        for job, future in reversed(list(zip(jobs[1:], offered, strict=True))):  # the pool takes the first
            if future.cancel():
                job()
    finally:
        for future in offered:
            future.cancel()
        # Nothing left running. (Not waiting for the cancelled: one counts as done only once a
        # pool thread has dropped it, and the pool's threads may all be callers waiting here.)
        begun = [future for future in offered if not future.cancelled()]
        wait(begun)
    for future in begun:
        future.result()


def ordered(work: Callable[[_T], _R], items: Iterable[_T]) -> Iterator[_R]:
    """``work(item)`` of each item on the pool, a thread's worth ahead of the one given (one
    queued per thread besides the one running), the results in the items' order. Stopped early
    -- an error, or the caller closing the iterator -- the items not begun are dropped and
    those running waited for: nothing is left running."""
    items = iter(items)
    pending = deque(pool().submit(work, item) for item in islice(items, 2 * size()))
    try:
        while pending:
            result = pending.popleft().result()
            pending.extend(pool().submit(work, item) for item in islice(items, 1))
            yield result
    finally:
        for future in pending:
            future.cancel()
        wait(pending)
