"""What the routes of one worker process share: settings, libraries, admission, memory budget,
the thread pools, open WebSocket sessions, the drain flag and the test hooks."""

from __future__ import annotations

import asyncio
import contextlib
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from starlette.requests import HTTPConnection

from service import memory
from service.admission import Admission
from service.budget import MemoryBudget
from service.errors import ApiError
from service.libraries import LibraryRegistry
from service.pipe import Pipe
from service.prometheus import Metrics
from service.settings import Settings
from synth_core.compiled.scratch import Shelf


class State:
    """Everything the routes share within one worker process."""

    def __init__(self, settings: Settings, registry: LibraryRegistry) -> None:
        self.settings, self.registry = settings, registry
        self.metrics = Metrics()
        self.admission = Admission(settings.max_in_flight, settings.max_queued, self.metrics)
        self.memory = MemoryBudget(settings.memory_budget_mb, self.metrics)
        self.pipes: set[Pipe] = set()  # answers going out now (their bytes waiting: /metrics)
        self.metrics.pipes = self.pipes
        self.pool = ThreadPoolExecutor(settings.max_in_flight, thread_name_prefix="synth")
        self.decoder = ThreadPoolExecutor(1, thread_name_prefix="decode")  # big bodies, one at a time
        self.scratches = Shelf()  # live sessions' chunk buffers, kept from session to session
        self.draining = False
        self.drain = asyncio.Event()  # set on SIGTERM: WebSocket sessions close with 1001
        self.sessions: set[Any] = set()  # open WebSocket sessions (service.ws_session.Session)
        self.sessions_closed = asyncio.Event()
        # Test hooks (settings.test_hooks): a worker about to synthesize sets `held` and waits
        # until `hold` is set again; /_test/hold clears it, /_test/release sets it.
        self.hold = threading.Event()
        self.held = threading.Event()
        self.hold.set()

    def held_by_test(self) -> None:
        """From a pool thread, with test hooks on: wait while a test holds the workers."""
        if self.settings.test_hooks:
            self.held.set()
            self.hold.wait()

    def late(self, cancel: threading.Event) -> ApiError:
        """504: the deadline passed (the work stops at its next chunk)."""
        cancel.set()
        self.metrics.rejected["deadline"] += 1
        limit = self.settings.deadline_s
        return ApiError(504, "", f"synthesis took longer than the deadline of {limit:g} s (deadline_s); "
                                 "send fewer characters or frames per request")

    def keep_within_budget(self, loop: asyncio.AbstractEventLoop) -> None:
        """Memory freed and kept for reuse counts against the budget too: past the part the
        answers in flight leave free, it goes back to the OS (in a thread: trimming hundreds of
        MB takes a while)."""
        held = memory.kept()
        if held is not None and held > self.memory.limit - self.memory.used:
            loop.run_in_executor(None, memory.give_back)

    def count_cancelled(self, loop: asyncio.AbstractEventLoop) -> None:
        """From a pool thread: one more synthesis stopped early (counted on the event loop, which
        owns the metrics)."""
        def count() -> None:
            self.metrics.cancelled += 1

        with contextlib.suppress(RuntimeError):  # the loop is gone: so is /metrics
            loop.call_soon_threadsafe(count)


def state_of(connection: HTTPConnection) -> State:
    """The worker's :class:`State` (set by :func:`service.app.create_app`)."""
    state: State = connection.app.state.quadsynth
    return state
