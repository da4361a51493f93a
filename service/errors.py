"""One error shape for every refusal: ``{"error": {"status", "field", "message"}}`` (JSON)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from fastapi import Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException


class ApiError(Exception):
    def __init__(self, status: int, field: str, message: str, headers: dict[str, str] | None = None) -> None:
        super().__init__(f"{field}: {message}" if field else message)
        self.status, self.field, self.message, self.headers = status, field, message, headers


def error_body(status: int, field: str, message: str) -> dict[str, Any]:
    return {"error": {"status": status, "field": field, "message": message}}


def error_response(exc: ApiError) -> JSONResponse:
    return JSONResponse(error_body(exc.status, exc.field, exc.message), exc.status, headers=exc.headers)


def field_path(loc: Sequence[int | str], prefix: str = "") -> str:
    """("characters", 3, "points", "shape") -> "characters[3].points.shape"."""
    out = prefix
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


def from_validation(exc: ValidationError | RequestValidationError, prefix: str = "") -> ApiError:
    """The first problem pydantic found, with where it is (there may be thousands; one is enough
    to fix, and the count says how many)."""
    problems = exc.errors()
    first = problems[0]
    loc = [p for p in first["loc"] if p not in ("body", "query", "path")]
    more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
    return ApiError(422, field_path(loc, prefix), f"{first['msg']}{more}")


async def handle_api_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ApiError)
    return error_response(exc)


async def handle_validation_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    return error_response(from_validation(exc))


async def handle_http_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    return JSONResponse(error_body(exc.status_code, "", str(exc.detail)), exc.status_code,
                        headers=getattr(exc, "headers", None))
