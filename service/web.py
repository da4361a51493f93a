"""The browser side the service serves itself, so it works offline: the herd viewer (``/viewer``),
the JavaScript client it runs on (``/viewer/client``, the npm package in ``js/``), the vendored
third-party code (``/vendor``: three.js, msgpack, Swagger UI, ReDoc; ``scripts/vendor-web``) and
the API docs pages on those local assets instead of a CDN."""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles

STATIC = Path(__file__).resolve().parent / "static"


def client_dir() -> Path:
    """The JS client's sources: copied into the package by the Docker build, else the checkout's
    ``js/src`` (the same files; the npm package is their one home)."""
    packaged = STATIC / "client"
    return packaged if packaged.is_dir() else Path(__file__).resolve().parents[1] / "js" / "src"


def mount(app: FastAPI) -> None:
    """Add the viewer, its assets and the offline API docs to ``app`` (built with ``docs_url``
    and ``redoc_url`` None: FastAPI's own pages load their scripts from a CDN)."""
    app.mount("/vendor", StaticFiles(directory=STATIC / "vendor"), name="vendor")
    app.mount("/viewer/client", StaticFiles(directory=client_dir()), name="viewer-client")
    app.mount("/viewer/static", StaticFiles(directory=STATIC / "viewer"), name="viewer-static")

    @app.api_route("/", methods=["GET", "HEAD"], include_in_schema=False)
    async def home() -> RedirectResponse:
        return RedirectResponse("/viewer")

    @app.api_route("/viewer", methods=["GET", "HEAD"], include_in_schema=False)
    async def viewer() -> HTMLResponse:
        """The herd viewer: a live herd streamed from a simulation in the page."""
        return HTMLResponse((STATIC / "viewer" / "index.html").read_text(encoding="utf-8"))

    @app.get("/docs", include_in_schema=False)
    async def swagger() -> HTMLResponse:
        return get_swagger_ui_html(openapi_url=app.openapi_url or "/openapi.json", title=f"{app.title} - API",
                                   swagger_js_url="/vendor/swagger-ui/swagger-ui-bundle.js",
                                   swagger_css_url="/vendor/swagger-ui/swagger-ui.css",
                                   swagger_favicon_url="/viewer/static/favicon.svg")

    @app.get("/redoc", include_in_schema=False)
    async def redoc() -> HTMLResponse:
        return get_redoc_html(openapi_url=app.openapi_url or "/openapi.json", title=f"{app.title} - ReDoc",
                              redoc_js_url="/vendor/redoc/redoc.standalone.js",
                              redoc_favicon_url="/viewer/static/favicon.svg", with_google_fonts=False)
