"""synth_core.compiled.render_pool.ordered: parts of a work side by side, results in order, nothing left
running when stopped early; render_pool.shared: a thread's parts taken by idle threads, every part
run once, from every pool thread at once without a deadlock."""

from __future__ import annotations

import functools
import threading
import time
from concurrent.futures import wait

import pytest

from synth_core.compiled import render_pool


def test_results_come_in_the_items_order_whatever_order_they_finish_in() -> None:
    def work(i: int) -> tuple[int, str]:
        time.sleep(0.02 if i % 2 == 0 else 0.0)  # the even ones finish after the odd ones
        return i, threading.current_thread().name

    results = list(render_pool.ordered(work, range(9)))
    assert [i for i, _ in results] == list(range(9))
    assert all(name.startswith("render") for _, name in results)  # on the pool, not the caller


def test_an_error_stops_the_rest_with_nothing_left_running() -> None:
    started: list[int] = []
    running = threading.Event()

    def work(i: int) -> int:
        started.append(i)
        if i == 1:
            raise ValueError("part 1 failed")
        running.set()
        time.sleep(0.05)
        return i

    results = render_pool.ordered(work, range(100))
    assert next(results) == 0
    with pytest.raises(ValueError, match="part 1 failed"):
        next(results)
    count = len(started)
    time.sleep(0.2)
    assert len(started) == count < 100  # the parts not begun were dropped, none began since
    assert render_pool.pool()._work_queue.qsize() == 0  # type: ignore[attr-defined]


def test_closing_early_waits_for_the_parts_running() -> None:
    done: list[int] = []

    def work(i: int) -> int:
        time.sleep(0.05)
        done.append(i)
        return i

    results = render_pool.ordered(work, range(50))
    assert next(results) == 0
    results.close()  # a caller that stops reading (a cancelled answer)
    finished = len(done)
    time.sleep(0.2)
    assert len(done) == finished < 50  # what was running had finished; nothing began after


def test_shared_parts_run_once_each_and_idle_threads_take_some() -> None:
    ran: list[tuple[int, str]] = []

    def part(i: int) -> None:
        time.sleep(0.02)
        ran.append((i, threading.current_thread().name))

    render_pool.shared([functools.partial(part, i) for i in range(8)])
    assert sorted(i for i, _ in ran) == list(range(8))
    assert dict(ran)[0] == threading.current_thread().name  # the first in the caller's thread
    helpers = {name for _, name in ran if name != threading.current_thread().name}
    assert helpers and all(name.startswith("render") for name in helpers)  # the idle pool took some


def test_shared_from_every_pool_thread_at_once_ends() -> None:
    """Each pool thread shares its own parts while the others are busy doing the same (a live
    session's shards): no thread waits for a part nobody has begun."""
    threads = render_pool.size()
    ran: list[tuple[int, int]] = []
    barrier = threading.Barrier(threads)

    def shard(s: int) -> None:
        barrier.wait()  # every pool thread busy here before any shares
        render_pool.shared([functools.partial(ran.append, (s, i)) for i in range(6)])

    futures = [render_pool.pool().submit(shard, s) for s in range(threads)]
    done, running = wait(futures, timeout=10)
    assert not running, "a pool thread waits for a part no thread has begun"
    for f in futures:
        f.result()
    assert sorted(ran) == [(s, i) for s in range(threads) for i in range(6)]


def test_shared_raises_a_parts_error_after_the_others_ended() -> None:
    ended: list[int] = []

    def part(i: int) -> None:
        if i == 2:
            raise ValueError("part 2 failed")
        time.sleep(0.02)
        ended.append(i)

    with pytest.raises(ValueError, match="part 2 failed"):
        render_pool.shared([functools.partial(part, i) for i in range(4)])
    count = len(ended)
    time.sleep(0.1)
    assert len(ended) == count  # none was still running when it raised


def test_one_thread_holds_inside_and_restores_after_even_on_an_error() -> None:
    numba = pytest.importorskip("numba")
    before = numba.get_num_threads()
    with render_pool.one_thread():
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == before
    with pytest.raises(RuntimeError), render_pool.one_thread():
        raise RuntimeError("a kernel failed")
    assert numba.get_num_threads() == before
