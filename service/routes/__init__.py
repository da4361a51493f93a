"""The service's routes, a module per concern; :func:`service.app.create_app` includes them in
this order (the OpenAPI document lists them so)."""

from __future__ import annotations

from fastapi import APIRouter

from service.routes import health, libraries, stream, synthesize, test_hooks


def routers(test_hooks_on: bool) -> list[APIRouter]:
    """Every router the app serves (the test hooks only when ``test_hooks_on``)."""
    found = [health.router, libraries.router, synthesize.router, stream.router]
    return [*found, test_hooks.router] if test_hooks_on else found
