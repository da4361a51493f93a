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
# How long a connection taken just before the listeners closed may take to send its request: a
# request from a client on the same network arrives in milliseconds; one that has not come by
# then is dropped as uvicorn does (the shutdown waits this long only while such a one is open).
LINGER_S = 1.0


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
    _answer_taken_connections()


def _answer_taken_connections() -> None:
    """uvicorn's shutdown closes its listeners, then at once every connection not in a request:
    one the server had just taken, whose request was still on its way, was closed unanswered
    (the client saw a reset: a rare failure of tests/test_drain.py). Here the listeners close
    first and such connections get up to ``LINGER_S`` to send their request, which is answered
    (503 from /readyz) before uvicorn's own shutdown goes on."""
    try:
        from uvicorn.server import Server
    except ImportError:  # served by something else: its shutdown is its own
        return
    if getattr(Server, "_quadsynth_linger", False):
        return
    original = Server.shutdown

    async def shutdown(self: Any, sockets: Any = None) -> None:
        for server in self.servers:
            server.close()
        for sock in sockets or []:
            sock.close()
        loop = asyncio.get_running_loop()
        until = loop.time() + LINGER_S
        while loop.time() < until and any(getattr(c, "cycle", False) is None
                                           for c in self.server_state.connections):
            await asyncio.sleep(0.01)
        await original(self, sockets)

    Server.shutdown = shutdown  # type: ignore[method-assign]
    Server._quadsynth_linger = True  # type: ignore[attr-defined]
