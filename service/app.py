"""FastAPI application factory: health, readiness and the library listing."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import JSONResponse

from api_schemas import Health, LibrariesResponse, Readiness
from service.libraries import LibraryRegistry, library_dir


def create_app(directory: Path | None = None) -> FastAPI:
    registry = LibraryRegistry(directory if directory is not None else library_dir())

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        registry.load()
        yield

    app = FastAPI(title="QuadSynth", version="0.1.0", lifespan=lifespan,
                  description="Fast motion synthesis for massive herds of quadrupeds (Sung 2011).")
    app.state.registry = registry

    @app.get("/livez", response_model=Health, tags=["health"])
    async def livez() -> Health:
        """The process is alive and its event loop answers."""
        return Health(status="ok")

    @app.get("/readyz", response_model=Readiness, tags=["health"],
             responses={503: {"model": Readiness, "description": "not ready yet"}})
    async def readyz() -> JSONResponse:
        """200 once the animal libraries are loaded, 503 before."""
        body = Readiness(status="ready" if registry.loaded else "starting",
                         libraries=len(registry.summaries))
        return JSONResponse(body.model_dump(), status_code=200 if registry.loaded else 503)

    @app.get("/v1/libraries", response_model=LibrariesResponse, tags=["libraries"])
    async def libraries() -> LibrariesResponse:
        """The animal libraries this service can synthesize with."""
        return LibrariesResponse(libraries=list(registry.summaries.values()))

    return app
