"""FastAPI application factory: the routes, thin over :mod:`service.jobs` and :mod:`synth_core`.

Synthesis runs in a thread pool (``max_in_flight`` threads per worker process; the numba
kernels release the GIL), so the event loop keeps answering health checks while it works.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import gc
import logging
import signal
import threading
import time
from collections.abc import AsyncIterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request, WebSocket
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.utils import get_openapi
from fastapi.responses import JSONResponse, PlainTextResponse, Response
from pydantic.json_schema import models_json_schema
from starlette.exceptions import HTTPException as StarletteHTTPException

from api_schemas import (
    ErrorResponse,
    GaitRange,
    Health,
    LibrariesResponse,
    LibraryDetail,
    Limits,
    Readiness,
    SynthesizeRequest,
    SynthesizeResponse,
)
from api_schemas.wire import BYTES_PER_JOINT_FRAME, DELTA_BYTES_PER_JOINT_FRAME, MSGPACK
from service import answer, body, budget, jobs, memory, web
from service import batch_ws as stream
from service.admission import Admission
from service.body import JSON, PiecesResponse
from service.budget import MemoryBudget
from service.errors import ApiError, handle_api_error, handle_http_error, handle_validation_error
from service.libraries import LibraryRegistry, library_dir
from service.packing import skeleton_id
from service.pipe import Pipe
from service.prometheus import Metrics, MetricsMiddleware
from service.settings import Settings
from synth_core.build.motion_graph import HUBS
from synth_core.compiled.scratch import Shelf

GLB = "model/gltf-binary"  # glTF 2.0 binary media type (IANA)

log = logging.getLogger("quadsynth.service")


def _errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    return {code: {"model": ErrorResponse} for code in codes}


def _binary_body(model: type, description: str) -> dict[str, Any]:
    ref = {"$ref": f"#/components/schemas/{model.__name__}"}
    return {"description": description,
            "content": {MSGPACK: {"schema": ref}, body.JSON: {"schema": ref}}}


def _with_body_schemas(app: FastAPI) -> None:
    """The OpenAPI document with the models of the bodies that routes read and write themselves
    (msgpack or JSON, not through FastAPI's parameters), so their ``$ref``s resolve."""
    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            spec = get_openapi(title=app.title, version=app.version, description=app.description,
                               routes=app.routes)
            _, defs = models_json_schema([(SynthesizeRequest, "validation"),
                                          (SynthesizeResponse, "serialization")],
                                         ref_template="#/components/schemas/{model}")
            spec.setdefault("components", {}).setdefault("schemas", {}).update(defs["$defs"])
            app.openapi_schema = spec
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


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
        self.sessions: set[Any] = set()  # open WebSocket sessions (service.batch_ws.Session)
        self.sessions_closed = asyncio.Event()
        # Test hooks (settings.test_hooks): a worker about to synthesize sets `held` and waits
        # until `hold` is set again; /_test/hold clears it, /_test/release sets it.
        self.hold = threading.Event()
        self.held = threading.Event()
        self.hold.set()

    def _held(self) -> None:
        self.held.set()
        self.hold.wait()

    def _late(self, job: jobs.Job) -> ApiError:
        job.cancel.set()  # the work stops at its next chunk
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

    async def answer(self, job: jobs.Job, meta: dict[str, Any], as_json: bool,
                     input_bytes: int) -> PiecesResponse:
        """The answer to ``job`` (:mod:`service.answer`; msgpack, or JSON text), sent while it is
        made: the pool thread renders and packs a chunk of characters while the network carries
        the one before, and waits when the client is not taking them (:class:`service.pipe.Pipe`).

        Until the answer starts (the batch checked and prepared): 503 when the worker is busy or
        its memory budget (:mod:`service.budget`) has no room for this answer, 422 for a bad
        trajectory or too many frames after resampling, 504 past the deadline. After, the
        deadline, a failure or a client that takes nothing for ``send_timeout_s`` can only cut
        the answer short (the connection closes before its Content-Length). The admission slot
        and the memory reserved are given back when the work is done and the last byte has
        left, not before."""
        bank = self.registry.banks[job.request.animal]
        loop = asyncio.get_running_loop()
        end = loop.time() + self.settings.deadline_s
        estimate = functools.partial(
            budget.answer_bytes, joints=bank.skeleton.n_joints,
            bytes_per_joint_frame=BYTES_PER_JOINT_FRAME.get(job.request.encoding,
                                                            int(DELTA_BYTES_PER_JOINT_FRAME)),
            as_json=as_json,
            buffer_bytes=self.settings.answer_buffer_bytes, input_bytes=input_bytes)
        reservation = self.memory.reserve(estimate(len(job.lengths), job.out_frames))
        pipe = Pipe(loop, self.settings.answer_buffer_bytes)
        left = 2  # the work and the sending: both end before the slot and the memory are free

        def work() -> tuple[int, float]:
            try:
                if self.settings.test_hooks:
                    self._held()
                t0 = time.perf_counter()
                frames = answer.produce(job, bank, meta, pipe.put, as_json,
                                        lambda c, t: reservation.resize(estimate(c, t)))
                return frames, time.perf_counter() - t0
            except BaseException as exc:  # noqa: BLE001 - handed to the event loop, raised there
                if isinstance(exc, jobs.Cancelled):
                    self.count_cancelled(loop)
                pipe.put(exc)
                raise

        def one_ended() -> None:
            nonlocal left
            left -= 1
            if left == 0:
                release()
                reservation.release()
                self.keep_within_budget(loop)
                if pipe in self.pipes:
                    self.pipes.discard(pipe)
                    self.metrics.answer_bytes += pipe.produced

        def worked(future: asyncio.Future[tuple[int, float]]) -> None:
            if not future.cancelled() and future.exception() is None:
                frames, seconds = future.result()
                self.metrics.character_frames += frames
                self.metrics.synthesis_seconds += seconds
                self.metrics.syntheses += 1
            one_ended()

        async def next_item() -> Any:
            try:
                item = await asyncio.wait_for(pipe.get(), max(end - loop.time(), 0.0))
            except TimeoutError:
                raise self._late(job) from None
            if isinstance(item, BaseException):
                raise item
            return item

        try:
            try:
                release = await asyncio.wait_for(self.admission.admit(), max(end - loop.time(), 0.0))
            except TimeoutError:
                raise self._late(job) from None
        except BaseException:
            reservation.release()
            raise
        self.pipes.add(pipe)
        loop.run_in_executor(self.pool, work).add_done_callback(worked)
        try:
            length = await next_item()
        except BaseException:
            job.cancel.set()
            pipe.close()
            one_ended()
            raise

        async def pieces() -> AsyncIterator[bytes]:
            got = 0
            try:
                while got < length:
                    item = await next_item()
                    got += len(item)
                    yield item
            except Exception as exc:  # noqa: BLE001 - the answer has started: it can only be cut short
                log.warning("answer to a synthesize request cut short: %s: %s", type(exc).__name__, exc)

        async def close(complete: bool) -> None:
            if not complete:
                job.cancel.set()  # a client that left or stalled: the work stops at its next chunk
            pipe.close()
            one_ended()

        return PiecesResponse(pieces(), length, JSON if as_json else MSGPACK, close, pipe.sent,
                              self.settings.send_timeout_s)


SMALL_BODY = 64 * 1024  # bodies below this are decoded on the event loop (a thread costs more)


DRAIN_SESSIONS_S = 2.0  # how long SIGTERM waits for WebSocket sessions to close (1001) first


def _install_drain(state: State) -> None:
    """On SIGTERM: /readyz turns 503 and WebSocket sessions close with 1001; then uvicorn's own
    handler stops accepting and lets in-flight requests finish within its graceful timeout.
    (Its own shutdown would close WebSockets with 1012 -- so they go first.)"""
    previous = signal.getsignal(signal.SIGTERM)
    loop = asyncio.get_running_loop()

    async def drain(signum: int, frame: Any) -> None:
        state.drain.set()
        for session in list(state.sessions):
            session.ack.set()  # a writer waiting for acks notices now
        if state.sessions:
            state.sessions_closed.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(state.sessions_closed.wait(), DRAIN_SESSIONS_S)
        if callable(previous):
            previous(signum, frame)

    def on_term(signum: int, frame: Any) -> None:
        if state.draining:  # the supervisor's SIGTERM after its fast one (service.supervisor)
            return
        state.draining = True
        log.info("SIGTERM: draining")
        if state.settings.test_hooks:  # a test holding the workers cannot reach /_test/release now
            threading.Timer(1.0, state.hold.set).start()
        loop.call_soon_threadsafe(lambda: loop.create_task(drain(signum, frame)))

    try:
        signal.signal(signal.SIGTERM, on_term)
    except ValueError:  # not the main thread (an embedding server): nothing to chain
        pass


def compile_kernels(directory: Path | None = None) -> None:
    """Compile (or load) every kernel the service uses, so numba's on-disk cache holds them.

    ``quadsynth serve`` runs this in a process of its own before the workers start: then every
    worker loads the same machine code from the cache. A kernel compiled in the process that
    uses it and the same kernel loaded from the cache differ in the last bit of some leg
    rotations (float32, measured), so without this the first process after an empty cache
    would answer slightly differently from every later one."""
    registry = LibraryRegistry(directory if directory is not None else library_dir())
    registry.load()
    warm_up(registry)


def warm_up(registry: LibraryRegistry) -> None:
    """Load (or compile) the kernels and packers before /readyz says ready, so the first
    request does not pay for it."""
    import numpy as np

    from api_schemas import delta
    from api_schemas.packing import pack_rotations
    from synth_core.runtime.live import LiveSynth
    from synth_core.runtime.streaming import BatchStream
    from synth_core.runtime.synthesis import synthesize

    path = np.zeros((1, 30, 3))
    path[0, :, 2] = np.linspace(0.0, 0.3, 30)
    # A live session's kernels take views of its buffers: two characters, so that they are views
    # as in any real session (of one, numba sees contiguous arrays and compiles another version).
    walk = np.zeros((2, 200, 3))
    walk[:, :, 2] = np.linspace(0.0, 8.0, 200)
    for bank in registry.banks.values():
        result = synthesize(bank, path)
        for encoding in ("s48", "i16"):
            pack_rotations(result.rotations, encoding)
        delta.encode(result.rotations, delta.joint_steps(bank.skeleton.parents, bank.skeleton.offsets))
        for _ in BatchStream(bank, path, chunk_frames=10).windows():
            pass
        live = LiveSynth(bank, 2, 30.0)
        live.append(walk)
        live.finish()


def create_app(directory: Path | None = None, settings: Settings | None = None) -> FastAPI:
    settings = settings if settings is not None else Settings.from_env()
    state = State(settings, LibraryRegistry(directory if directory is not None else library_dir()))

    def load() -> None:
        if settings.memory_tuning:
            state.metrics.memory_tuning = memory.tune()
        state.registry.load()
        warm_up(state.registry)
        # What start-up made lives as long as the process (libraries, compiled kernels, the
        # frameworks): kept out of the cyclic GC's full collections, which otherwise walk all of
        # it now and then -- a 60-70 ms pause, holding the GIL, in one request of ~15 here.
        gc.collect()
        gc.freeze()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        await asyncio.get_running_loop().run_in_executor(None, load)
        _install_drain(state)
        yield
        state.draining = True
        state.pool.shutdown(wait=False, cancel_futures=True)
        state.decoder.shutdown(wait=False, cancel_futures=True)

    # docs_url/redoc_url None: FastAPI's pages load Swagger UI and ReDoc from a CDN; service.web
    # serves them on vendored copies instead (offline).
    app = FastAPI(title="QuadSynth", version="0.1.0", lifespan=lifespan, docs_url=None, redoc_url=None,
                  description="Fast motion synthesis for massive herds of quadrupeds (Sung 2011). "
                              "Bodies are msgpack (application/vnd.msgpack) or JSON; arrays travel "
                              "as binary blobs -- see docs/wire-format.md. WebSocket /v1/stream (not "
                              "listed below: OpenAPI has no WebSockets) streams a batch in chunks "
                              "as it is made -- see docs/streaming.md.")
    app.state.quadsynth = state
    web.mount(app)
    _with_body_schemas(app)
    app.add_middleware(MetricsMiddleware, metrics=state.metrics)
    app.add_exception_handler(ApiError, handle_api_error)
    app.add_exception_handler(RequestValidationError, handle_validation_error)
    app.add_exception_handler(StarletteHTTPException, handle_http_error)
    registry = state.registry

    @app.get("/livez", response_model=Health, tags=["health"])
    async def livez() -> Health:
        """The process is alive and its event loop answers."""
        return Health(status="ok")

    @app.get("/readyz", response_model=Readiness, tags=["health"],
             responses={503: {"model": Readiness, "description":
                              "starting, a configured library missing or failed, or draining"}})
    async def readyz() -> JSONResponse:
        """200 once every configured animal library and every library file is loaded (and the
        kernels warmed up); 503 before, while any of them is missing or failed to load (the
        process keeps serving what it has: see ``library_status``), and from SIGTERM on."""
        status = ("draining" if state.draining else "starting" if not registry.loaded
                  else "ready" if registry.complete else "incomplete")
        code = 200 if status == "ready" else 503
        answer = Readiness(status=status, libraries=len(registry.summaries),
                           library_status=registry.status() if registry.loaded else [])
        return JSONResponse(answer.model_dump(), code)

    @app.get("/metrics", response_class=PlainTextResponse, tags=["health"])
    async def metrics() -> PlainTextResponse:
        """Prometheus text format, this worker process's counters."""
        return PlainTextResponse(state.metrics.render(), media_type="text/plain; version=0.0.4")

    @app.get("/v1/libraries", response_model=LibrariesResponse, tags=["libraries"])
    async def libraries() -> LibrariesResponse:
        """The animal libraries this service can synthesize with."""
        return LibrariesResponse(libraries=list(registry.summaries.values()))

    @app.get("/v1/libraries/{animal}", response_model=LibraryDetail, tags=["libraries"],
             responses=_errors(404))
    async def library(animal: str) -> LibraryDetail:
        """What a client needs to play the streams: joints, parents, rest offsets, feet, gaits."""
        if animal not in registry.libraries:
            loaded = ", ".join(sorted(registry.libraries))
            raise ApiError(404, "animal", f"unknown animal {animal!r}; loaded: {loaded}")
        lib, bank = registry.libraries[animal], registry.banks[animal]
        sk = lib.skeleton
        gaits = [GaitRange(index=HUBS.index(g), name=g, min_speed=float(m.speeds[0]),
                           max_speed=float(m.speeds[-1])) for g, m in lib.maps.items()]
        mesh_url = f"/v1/libraries/{animal}/mesh.glb" if animal in registry.meshes else None
        return LibraryDetail(animal=animal, skeleton_id=skeleton_id(animal, sk), fps=bank.fps,
                             joint_names=list(sk.names), parents=[int(p) for p in sk.parents],
                             offsets=sk.offsets.astype(float).tolist(),
                             end_sites=[bool(e) for e in sk.end_site],
                             feet={f.name: sk.names[f.end_effector] for f in sk.feet}, gaits=gaits,
                             mesh_url=mesh_url)

    @app.get("/v1/libraries/{animal}/mesh.glb", response_class=Response, tags=["libraries"],
             responses={200: {"description": "glTF 2.0 binary: one skinned mesh on the animal's skeleton "
                                             "in its rest pose (synth_core.export.mesh)",
                              "content": {GLB: {"schema": {"type": "string", "format": "binary"}}}},
                        **_errors(404)})
    async def library_mesh(animal: str) -> Response:
        """The animal's skinned mesh: a node per joint named and ordered as
        `GET /v1/libraries/{animal}` lists them, skin joints in that order, inverse bind
        matrices of the rest pose; Y up, metres, facing +Z."""
        if animal in registry.mesh_errors:
            raise ApiError(404, "animal", f"no mesh for {animal!r}: {registry.mesh_errors[animal]}")
        if animal not in registry.meshes:
            loaded = ", ".join(sorted(registry.libraries))
            raise ApiError(404, "animal", f"unknown animal {animal!r}; loaded: {loaded}")
        return Response(registry.meshes[animal], media_type=GLB)

    @app.get("/v1/limits", response_model=Limits, tags=["libraries"])
    async def limits() -> Limits:
        """The request limits of this service and each rotation encoding's size and error."""
        return settings.published()

    @app.post("/v1/synthesize", tags=["synthesis"],
              responses={200: _binary_body(SynthesizeResponse, "motion per character"),
                         **_errors(404, 408, 413, 415, 422, 503, 504)},
              openapi_extra={"requestBody": {"required": True, **_binary_body(
                  SynthesizeRequest, "characters' trajectories and options")}})
    async def synthesize(request: Request) -> Response:
        """Trajectories in, packed joint-rotation streams out (docs/wire-format.md).

        Body and answer in msgpack (``application/vnd.msgpack``, also ``application/x-msgpack``,
        ``application/msgpack``) or JSON, by Content-Type and Accept. The same body and seed
        give byte-identical answers."""
        if not registry.loaded:
            raise ApiError(503, "", "libraries are still loading", headers={"Retry-After": "1"})
        raw = await body.read_body(request, settings.max_body_bytes, settings.body_timeout_s)
        content_type = request.headers.get("content-type")

        def parse() -> jobs.Job:
            return jobs.parse(body.decode(raw, content_type), settings, registry.banks)

        # A big body is decoded and validated in a thread of its own (one at a time): an 8 MiB
        # msgpack of empty arrays took 0.9 s, and on the event loop /livez waited for it.
        job = (parse() if len(raw) < SMALL_BODY
               else await asyncio.get_running_loop().run_in_executor(state.decoder, parse))
        req = job.request
        sk = registry.libraries[req.animal].skeleton
        meta = {"animal": req.animal, "skeleton_id": skeleton_id(req.animal, sk),
                "fps": registry.banks[req.animal].fps, "encoding": req.encoding}
        return await state.answer(job, meta, not body.wants_msgpack(request), len(raw))

    @app.websocket("/v1/stream")
    async def stream_route(ws: WebSocket) -> None:
        """Batch streaming over WebSocket: binary msgpack messages, docs/streaming.md."""
        await stream.session(ws, state)

    if settings.test_hooks:
        @app.post("/_test/hold", include_in_schema=False)
        async def hold() -> dict[str, str]:
            state.held.clear()
            state.hold.clear()
            return {"status": "holding"}

        @app.post("/_test/release", include_in_schema=False)
        async def release() -> dict[str, str]:
            state.hold.set()
            return {"status": "released"}

        @app.get("/_test/held", include_in_schema=False)
        async def held() -> dict[str, bool]:
            return {"held": state.held.is_set()}

    return app
