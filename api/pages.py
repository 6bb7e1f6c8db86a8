"""What a browser opens: the dashboard at ``/`` and the interactive API docs, all offline.

The dashboard is static HTML, CSS and JavaScript shipped as package data of ``api``
(``api/static``), read with :mod:`importlib.resources`; it talks to the same JSON routes as
any client. ``/docs`` (Swagger UI) and ``/redoc`` load their scripts from this service: the
``fastapi-offline`` wheel carries them, so a stand network without internet still has docs.
"""

from __future__ import annotations

from importlib import resources

from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

#: Where the dashboard's files and the docs' assets are served.
STATIC_URL = "/static"
DOCS_ASSETS_URL = "/static-docs"


def _dashboard_html() -> str:
    return (resources.files("api") / "static" / "index.html").read_text(encoding="utf-8")


def install(app: FastAPI) -> None:
    """Add ``/``, ``/docs``, ``/redoc`` and their static files to ``app`` (created with
    ``docs_url=None, redoc_url=None``)."""
    app.mount(STATIC_URL, StaticFiles(packages=[("api", "static")]), name="static")
    app.mount(DOCS_ASSETS_URL, StaticFiles(packages=[("fastapi_offline", "static")]),
              name="static-docs")
    openapi_url = app.openapi_url or "/openapi.json"

    @app.get("/", include_in_schema=False)
    def dashboard() -> HTMLResponse:
        return HTMLResponse(_dashboard_html())

    @app.get("/docs", include_in_schema=False)
    def swagger() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=openapi_url, title=f"{app.title} - Swagger UI",
            swagger_js_url=f"{DOCS_ASSETS_URL}/swagger-ui-bundle.js",
            swagger_css_url=f"{DOCS_ASSETS_URL}/swagger-ui.css",
            swagger_favicon_url=f"{DOCS_ASSETS_URL}/favicon.png",
            # no badge from the public validator: the page makes no request off the service
            swagger_ui_parameters={**(app.swagger_ui_parameters or {}), "validatorUrl": None})

    @app.get("/redoc", include_in_schema=False)
    def redoc() -> HTMLResponse:
        return get_redoc_html(
            openapi_url=openapi_url, title=f"{app.title} - ReDoc",
            redoc_js_url=f"{DOCS_ASSETS_URL}/redoc.standalone.js",
            redoc_favicon_url=f"{DOCS_ASSETS_URL}/favicon.png", with_google_fonts=False)
