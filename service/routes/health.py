"""Liveness, readiness and the Prometheus counters."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, PlainTextResponse

from api_schemas import Health, Readiness
from service.state import state_of

router = APIRouter(tags=["health"])


@router.get("/livez", response_model=Health)
async def livez() -> Health:
    """The process is alive and its event loop answers."""
    return Health(status="ok")


@router.get("/readyz", response_model=Readiness,
            responses={503: {"model": Readiness, "description":
                             "starting, a configured library missing or failed, or draining"}})
async def readyz(request: Request) -> JSONResponse:
    """200 once every configured animal library and every library file is loaded (and the
    kernels warmed up); 503 before, while any of them is missing or failed to load (the
    process keeps serving what it has: see ``library_status``), and from SIGTERM on."""
    state = state_of(request)
    registry = state.registry
    status = ("draining" if state.draining else "starting" if not registry.loaded
              else "ready" if registry.complete else "incomplete")
    code = 200 if status == "ready" else 503
    answer = Readiness(status=status, libraries=len(registry.summaries),
                       library_status=registry.status() if registry.loaded else [])
    return JSONResponse(answer.model_dump(), code)


@router.get("/metrics", response_class=PlainTextResponse)
async def metrics(request: Request) -> PlainTextResponse:
    """Prometheus text format, this worker process's counters."""
    return PlainTextResponse(state_of(request).metrics.render(), media_type="text/plain; version=0.0.4")
