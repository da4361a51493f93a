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


NAMED = 3  # further problems named after the first (there may be thousands)


def problems_error(problems: Sequence[Any], prefix: str = "", first_index: int = 0) -> ApiError:
    """The 422 of pydantic's ``problems``: the first one's field and message, then the next
    ``NAMED`` named by field and message and the count of the rest. ``first_index``: added to a
    leading list index (the problems of a slice of a list)."""
    def where(problem: Any) -> str:
        loc = [p for p in problem["loc"] if p not in ("body", "query", "path")]
        if loc and isinstance(loc[0], int):
            loc[0] += first_index
        return field_path(loc, prefix)

    named = [f"{where(p)}: {p['msg']}" for p in problems[1:1 + NAMED]]
    rest = len(problems) - 1 - len(named)
    more = "; ".join(named + ([f"{rest} more"] if rest else []))
    return ApiError(422, where(problems[0]), problems[0]["msg"] + (f" (also {more})" if more else ""))


def from_validation(exc: ValidationError | RequestValidationError, prefix: str = "") -> ApiError:
    """The problems pydantic found (:func:`problems_error`)."""
    return problems_error(exc.errors(), prefix)


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
