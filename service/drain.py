"""SIGTERM: /readyz turns 503 and WebSocket sessions close with 1001; then uvicorn's own handler
stops accepting and lets in-flight requests finish within its graceful timeout. (Its own
shutdown would close WebSockets with 1012 -- so they go first.)"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import threading
from typing import Any

from service.state import State

log = logging.getLogger("quadsynth.service")

DRAIN_SESSIONS_S = 2.0  # how long SIGTERM waits for WebSocket sessions to close (1001) first


async def _drain(state: State, previous: Any, signum: int, frame: Any) -> None:
    state.drain.set()
    for session in list(state.sessions):
        session.ack.set()  # a writer waiting for acks notices now
    if state.sessions:
        state.sessions_closed.clear()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(state.sessions_closed.wait(), DRAIN_SESSIONS_S)
    if callable(previous):
        previous(signum, frame)


def install_drain(state: State) -> None:
    """SIGTERM drains ``state``'s worker, then runs the handler installed before (uvicorn's)."""
    previous = signal.getsignal(signal.SIGTERM)
    loop = asyncio.get_running_loop()

    def on_term(signum: int, frame: Any) -> None:
        if state.draining:  # the supervisor's SIGTERM after its fast one (service.supervisor)
            return
        state.draining = True
        log.info("SIGTERM: draining")
        if state.settings.test_hooks:  # a test holding the workers cannot reach /_test/release now
            threading.Timer(1.0, state.hold.set).start()
        loop.call_soon_threadsafe(lambda: loop.create_task(_drain(state, previous, signum, frame)))

    try:
        signal.signal(signal.SIGTERM, on_term)
    except ValueError:  # not the main thread (an embedding server): nothing to chain
        pass
