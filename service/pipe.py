"""A bounded hand-over of an answer's pieces from the pool thread that makes them to the event
loop that sends them: back-pressure from the socket to the synthesis.

The producer (a pool thread) blocks in :meth:`Pipe.put` while the pieces handed over and not
yet sent add up to ``limit`` bytes or more; the event loop reports each piece it has sent with
:meth:`Pipe.sent`. So a client that stops reading holds at most ``limit`` bytes (plus the one
piece being sent) in the worker, instead of the whole answer: an unbounded queue let a 16.7 KB
request pin a 1 GB answer (issue 34). :meth:`Pipe.close` wakes a blocked producer, which then
stops (:class:`service.jobs.Cancelled`).
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from typing import Any

from service import jobs


class Pipe:
    def __init__(self, loop: asyncio.AbstractEventLoop, limit: int) -> None:
        self.loop, self.limit = loop, limit
        self.items: asyncio.Queue[Any] = asyncio.Queue()
        self.pending = 0  # bytes put and not yet sent
        self.produced = 0  # bytes put in all
        self.blocked = False  # the producer waits for the socket now
        self.closed = False
        self._room = threading.Condition()

    def put(self, item: Any) -> None:
        """From the producer thread: ``item`` to the event loop (bytes: waiting first while the
        pieces not yet sent reach ``limit``; one piece alone always goes, whatever its size)."""
        size = len(item) if isinstance(item, bytes | bytearray | memoryview) else 0
        with self._room:
            while size and not self.closed and self.pending and self.pending + size > self.limit:
                self.blocked = True
                self._room.wait()
            self.blocked = False
            if self.closed:
                if size:
                    raise jobs.Cancelled
                return  # the end of an answer nobody waits for any more
            self.pending += size
            self.produced += size
        with contextlib.suppress(RuntimeError):  # the loop is gone: nobody is waiting
            self.loop.call_soon_threadsafe(self.items.put_nowait, item)

    async def get(self) -> Any:
        return await self.items.get()

    def sent(self, size: int) -> None:
        """``size`` bytes of what was put have left: room for as many more."""
        with self._room:
            self.pending -= size
            self._room.notify_all()

    def close(self) -> None:
        """No more pieces are wanted: a producer waiting (or putting next) stops."""
        with self._room:
            self.closed = True
            self._room.notify_all()
