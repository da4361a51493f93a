"""synth_core.render_pool.ordered: parts of a work side by side, results in order, nothing left
running when stopped early."""

from __future__ import annotations

import threading
import time

import pytest

from synth_core import render_pool


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
