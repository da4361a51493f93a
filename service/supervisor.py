"""uvicorn's multi-process supervisor, made to drain as the docs say when SIGTERM comes.

uvicorn's parent process only queues the signal, and acts on it at its next half-second tick,
after pinging every worker -- so with two workers /readyz stayed 200 for 0.7 s after SIGTERM
(issue 34) -- and it keeps its own copy of the listening socket open until the last worker
has exited: connections made meanwhile were taken into the kernel's queue, never accepted,
and reset at the end (1-4.4 s after SIGTERM). Installed by ``quadsynth serve`` before uvicorn
starts, this makes the parent, on SIGTERM, close its copy of the socket and pass the signal to
every worker at once: each turns /readyz 503, closes its WebSocket sessions with 1001, stops
accepting (the socket closes with the last worker's copy: later connections are refused, not
reset) and finishes what it has in flight within the graceful timeout.
"""

from __future__ import annotations

import contextlib
import os
import signal
from typing import Any


def install() -> None:
    from uvicorn.supervisors import multiprocess

    supervisor = multiprocess.Multiprocess
    if getattr(supervisor, "_quadsynth_drain", False):
        return
    original = supervisor.__init__

    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        original(self, *args, **kwargs)
        queue = signal.getsignal(signal.SIGTERM)  # uvicorn's: acted on at its next tick

        def on_term(signum: int, frame: Any) -> None:
            for sock in self.sockets:
                with contextlib.suppress(OSError):
                    sock.close()
            for process in self.processes:
                if process.pid is not None and process.exitcode is None:
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(process.pid, signal.SIGTERM)
            if callable(queue):
                queue(signum, frame)

        signal.signal(signal.SIGTERM, on_term)

    supervisor.__init__ = __init__  # type: ignore[method-assign]
    supervisor._quadsynth_drain = True  # type: ignore[attr-defined]
