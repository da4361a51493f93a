"""Pydantic models for the service's JSON bodies."""

from __future__ import annotations

from pydantic import BaseModel, Field


class Health(BaseModel):
    status: str = Field(description="'ok' while the process serves requests")


class Readiness(BaseModel):
    status: str = Field(description="'ready', 'starting' or 'draining'")
    libraries: int = Field(description="number of animal libraries loaded")


class LibrarySummary(BaseModel):
    animal: str = Field(description="library name, e.g. 'horse'")
    joints: int
    fps: float
    gaits: list[str]
    source: str = Field(description="file the library was loaded from")


class LibrariesResponse(BaseModel):
    libraries: list[LibrarySummary]
