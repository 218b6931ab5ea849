"""The web pages: ``GET /`` (the live map), ``GET /setup`` and their scripts under ``/web``.

Open without a token: pages and scripts carry no data; they read it from the ``/v1`` routes
with the token the user gives them.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, FastAPI
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles

WEB_DIR = Path(__file__).resolve().parent.parent / "web"


def mount_pages(app: FastAPI) -> None:
    """``/web/*`` as static files (a mount belongs to the app: routers do not carry mounts)."""
    app.mount("/web", StaticFiles(directory=WEB_DIR), name="web")


def pages_router() -> APIRouter:
    router = APIRouter(include_in_schema=False)

    @router.get("/")
    def index() -> FileResponse:
        return FileResponse(WEB_DIR / "index.html", headers={"Cache-Control": "no-cache"})

    @router.get("/setup")
    def setup_page() -> FileResponse:
        return FileResponse(WEB_DIR / "setup.html", headers={"Cache-Control": "no-cache"})

    return router
