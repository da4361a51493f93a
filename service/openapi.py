"""Pieces of the OpenAPI document the routes' decorators do not make themselves."""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic.json_schema import models_json_schema

from api_schemas import ErrorResponse, SynthesizeRequest, SynthesizeResponse
from api_schemas.wire import MSGPACK
from service.body import JSON


def errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """``responses`` entries of these status codes, each with the typed error body."""
    return {code: {"model": ErrorResponse} for code in codes}


def binary_body(model: type, description: str) -> dict[str, Any]:
    """A body read or written by the route itself, in msgpack or JSON, of ``model``'s schema."""
    ref = {"$ref": f"#/components/schemas/{model.__name__}"}
    return {"description": description,
            "content": {MSGPACK: {"schema": ref}, JSON: {"schema": ref}}}


def with_body_schemas(app: FastAPI) -> None:
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
