"""The answer of ``POST /v1/synthesize`` made in the worker pool and sent while it is made.

The pool thread renders and packs a chunk of characters (:func:`service.answer.produce`) while
the network carries the one before, and waits when the client is not taking them
(:class:`service.pipe.Pipe`). Until the answer starts (the batch checked and prepared): 503 when
the worker is busy or its memory budget (:mod:`service.budget`) has no room for this answer, 422
for a bad trajectory or too many frames after resampling, 504 past the deadline. After, the
deadline, a failure or a client that takes nothing for ``send_timeout_s`` can only cut the
answer short (the connection closes before its Content-Length, or before a chunked answer's last
chunk: a delta or level-of-detail answer, whose length is known only once it is all packed, goes
out chunked as its characters are made). The admission slot and the
memory reserved are given back when the work is done and the last byte has left, not before.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

from api_schemas.wire import BYTES_PER_JOINT_FRAME, DELTA_BYTES_PER_JOINT_FRAME, MSGPACK
from service import answer, budget, jobs
from service.body import JSON, PiecesResponse
from service.pipe import Pipe
from service.state import State

log = logging.getLogger("quadsynth.service")


class Answer:
    """One answer under way: its work in the pool, its pieces on their way out. The slot and
    the memory are released once both have ended."""

    def __init__(self, state: State, job: jobs.Job, meta: dict[str, Any], as_json: bool,
                 input_bytes: int) -> None:
        self.state, self.job, self.meta, self.as_json = state, job, meta, as_json
        self.bank = state.registry.banks[job.request.animal]
        self.loop = asyncio.get_running_loop()
        self.end = self.loop.time() + state.settings.deadline_s
        self.estimate = functools.partial(
            budget.answer_bytes, joints=self.bank.skeleton.n_joints,
            bytes_per_joint_frame=BYTES_PER_JOINT_FRAME.get(job.request.encoding,
                                                            int(DELTA_BYTES_PER_JOINT_FRAME)),
            as_json=as_json,
            buffer_bytes=state.settings.answer_buffer_bytes, input_bytes=input_bytes)
        self.reservation = state.memory.reserve(self.estimate(len(job.lengths), job.out_frames))
        self.pipe = Pipe(self.loop, state.settings.answer_buffer_bytes)
        self.whole = False  # every piece of the answer handed to the server
        self.left = 2  # the work and the sending: both end before the slot and the memory are free
        self.release: Callable[[], None] = lambda: None

    def work(self) -> tuple[int, float]:
        """In a pool thread: the answer's pieces into the pipe; the character-frames and seconds."""
        try:
            self.state.held_by_test()
            t0 = time.perf_counter()
            frames = answer.produce(self.job, self.bank, self.meta, self.pipe.put, self.as_json,
                                    lambda c, t: self.reservation.resize(self.estimate(c, t)))
            return frames, time.perf_counter() - t0
        except BaseException as exc:  # noqa: BLE001 - handed to the event loop, raised there
            if isinstance(exc, jobs.Cancelled):
                self.state.count_cancelled(self.loop)
            self.pipe.put(exc)
            raise

    def one_ended(self) -> None:
        self.left -= 1
        if self.left == 0:
            self.release()
            self.reservation.release()
            self.state.keep_within_budget(self.loop)
            if self.pipe in self.state.pipes:
                self.state.pipes.discard(self.pipe)
                self.state.metrics.answer_bytes += self.pipe.produced

    def worked(self, future: asyncio.Future[tuple[int, float]]) -> None:
        if not future.cancelled() and future.exception() is None:
            frames, seconds = future.result()
            metrics = self.state.metrics
            metrics.character_frames += frames
            metrics.synthesis_seconds += seconds
            metrics.syntheses += 1
        self.one_ended()

    def time_left(self) -> float:
        return max(self.end - self.loop.time(), 0.0)

    async def next_item(self) -> Any:
        try:
            item = await asyncio.wait_for(self.pipe.get(), self.time_left())
        except TimeoutError:
            raise self.state.late(self.job.cancel) from None
        if isinstance(item, BaseException):
            raise item
        return item

    async def admit(self) -> None:
        """An admission slot within the deadline (503 when the worker is full, 504 past it)."""
        try:
            try:
                self.release = await asyncio.wait_for(self.state.admission.admit(), self.time_left())
            except TimeoutError:
                raise self.state.late(self.job.cancel) from None
        except BaseException:
            self.reservation.release()
            raise

    async def start(self) -> int | None:
        """The work started; the answer's length once the batch is prepared (None: known only
        once it is all packed, :func:`service.answer.produce_detailed`)."""
        self.state.pipes.add(self.pipe)
        self.loop.run_in_executor(self.state.pool, self.work).add_done_callback(self.worked)
        try:
            length: int | None = await self.next_item()
        except BaseException:
            self.job.cancel.set()
            self.pipe.close()
            self.one_ended()
            raise
        return length

    async def pieces(self, length: int | None) -> AsyncIterator[bytes]:
        """The answer's pieces: ``length`` bytes of them, or (None) up to ``answer.END``;
        :attr:`whole` once they are all here."""
        got = 0
        try:
            while length is None or got < length:
                item = await self.next_item()
                if item is answer.END:
                    break
                got += len(item)
                yield item
            self.whole = True
        except Exception as exc:  # noqa: BLE001 - the answer has started: it can only be cut short
            log.warning("answer to a synthesize request cut short: %s: %s", type(exc).__name__, exc)

    async def close(self, complete: bool) -> None:
        if not complete:
            self.job.cancel.set()  # a client that left or stalled: the work stops at its next chunk
        self.pipe.close()
        self.one_ended()


async def respond(state: State, job: jobs.Job, meta: dict[str, Any], as_json: bool,
                  input_bytes: int) -> PiecesResponse:
    """The answer to ``job`` (:mod:`service.answer`; msgpack, or JSON text), sent while it is made."""
    run = Answer(state, job, meta, as_json, input_bytes)
    await run.admit()
    length = await run.start()
    return PiecesResponse(run.pieces(length), length, JSON if as_json else MSGPACK, run.close,
                          run.pipe.sent, state.settings.send_timeout_s, lambda: run.whole)
