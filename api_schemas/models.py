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
    joints: int = Field(description="number of joints, end sites included")
    feet: dict[str, str] = Field(description="foot (LF, RF, LH, RH) -> end-effector joint name")
    fps: float = Field(description="frame rate of the library's clips")
    gaits: list[str] = Field(description="gaits the library can synthesize (empty until built)")
    source: str = Field(description="'built-in' or the artifact file it was loaded from")


class LibrariesResponse(BaseModel):
    libraries: list[LibrarySummary]
