"""At most ``max_in_flight`` syntheses per process, ``max_queued`` waiting; beyond, 503.

Synthesis is CPU-bound and already uses every core, so queueing more work than this only makes
every caller wait longer: refusing early with ``Retry-After`` lets a load balancer try another
replica. Health and metrics routes never pass through here.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager

from service.errors import ApiError
from service.prometheus import Metrics

RETRY_AFTER_S = 1


class Admission:
    def __init__(self, max_in_flight: int, max_queued: int, metrics: Metrics) -> None:
        self.running = asyncio.Semaphore(max_in_flight)
        self.capacity = max_in_flight + max_queued
        self.metrics = metrics
        self.admitted = 0

    async def admit(self) -> Callable[[], None]:
        """A running slot (waiting for one in the queue; 503 when that is full too), held until
        the returned ``release`` is called (more calls do nothing): an answer sent in pieces
        gives its slot back when its work is done, not when a slow client has read it all."""
        if self.admitted >= self.capacity:
            self.metrics.rejected["overloaded"] += 1
            raise ApiError(503, "", f"busy: {self.admitted} requests running or queued in this worker "
                                    f"(max_in_flight + max_queued = {self.capacity}); retry shortly",
                           headers={"Retry-After": str(RETRY_AFTER_S)})
        self.admitted += 1
        self.metrics.in_flight = self.admitted
        try:
            await self.running.acquire()
        except BaseException:
            self._leave()
            raise
        held = True

        def release() -> None:
            nonlocal held
            if held:
                held = False
                self.running.release()
                self._leave()

        return release

    def _leave(self) -> None:
        self.admitted -= 1
        self.metrics.in_flight = self.admitted

    @asynccontextmanager
    async def slot(self) -> AsyncIterator[None]:
        release = await self.admit()
        try:
            yield
        finally:
            release()

    async def wait_turn(self) -> Callable[[], None]:
        """A running slot for work already admitted (a stream's next window): it waits its turn
        instead of being refused, and does not count against the queue; held until the returned
        ``release`` is called."""
        await self.running.acquire()
        return self.running.release

    @asynccontextmanager
    async def turn(self) -> AsyncIterator[None]:
        release = await self.wait_turn()
        try:
            yield
        finally:
            release()
