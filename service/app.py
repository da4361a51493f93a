"""FastAPI application factory: the routes (:mod:`service.routes`), thin over :mod:`service.jobs`
and :mod:`synth_core`, on one :class:`service.state.State` per worker process.

Synthesis runs in a thread pool (``max_in_flight`` threads per worker process; the numba
kernels release the GIL), so the event loop keeps answering health checks while it works.
"""

from __future__ import annotations

import asyncio
import gc
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException

from service import memory, web
from service.drain import install_drain
from service.errors import ApiError, handle_api_error, handle_http_error, handle_validation_error
from service.libraries import LibraryRegistry, library_dir
from service.openapi import with_body_schemas
from service.prometheus import MetricsMiddleware
from service.routes import routers
from service.settings import Settings
from service.state import State
from service.warmup import warm_up

DESCRIPTION = ("Fast motion synthesis for massive herds of quadrupeds (Sung 2011). "
               "Bodies are msgpack (application/vnd.msgpack) or JSON; arrays travel "
               "as binary blobs -- see docs/wire-format.md. WebSocket /v1/stream (not "
               "listed below: OpenAPI has no WebSockets) streams a batch in chunks "
               "as it is made, or a live session's frames as its points come (each "
               "points message may carry the points' ground velocity, m/s, which the "
               "low-latency mode reads for gait and heading) -- see docs/streaming.md.")


def _load(state: State) -> None:
    if state.settings.memory_tuning:
        state.metrics.memory_tuning = memory.tune()
    state.registry.load()
    warm_up(state.registry)
    # What start-up made lives as long as the process (libraries, compiled kernels, the
    # frameworks): kept out of the cyclic GC's full collections, which otherwise walk all of
    # it now and then -- a 60-70 ms pause, holding the GIL, in one request of ~15 here.
    gc.collect()
    gc.freeze()


@asynccontextmanager
async def _lifespan(app: FastAPI) -> AsyncIterator[None]:
    state: State = app.state.quadsynth
    await asyncio.get_running_loop().run_in_executor(None, _load, state)
    install_drain(state)
    yield
    state.draining = True
    state.pool.shutdown(wait=False, cancel_futures=True)
    state.decoder.shutdown(wait=False, cancel_futures=True)


def create_app(directory: Path | None = None, settings: Settings | None = None) -> FastAPI:
    settings = settings if settings is not None else Settings.from_env()
    # docs_url/redoc_url None: FastAPI's pages load Swagger UI and ReDoc from a CDN; service.web
    # serves them on vendored copies instead (offline).
    app = FastAPI(title="QuadSynth", version="0.1.0", lifespan=_lifespan, docs_url=None, redoc_url=None,
                  description=DESCRIPTION)
    app.state.quadsynth = state = State(settings, LibraryRegistry(directory or library_dir()))
    web.mount(app)
    with_body_schemas(app)
    app.add_middleware(MetricsMiddleware, metrics=state.metrics)
    app.add_exception_handler(ApiError, handle_api_error)
    app.add_exception_handler(RequestValidationError, handle_validation_error)
    app.add_exception_handler(StarletteHTTPException, handle_http_error)
    for router in routers(settings.test_hooks):
        app.include_router(router)
    return app
