"""The HTTP and WebSocket API (FastAPI): the app factory. Each route family is an ``APIRouter``
of its own module under ``service.api.routes``, built from the daemon's state
(``service.api.state.Daemon``) and the token check (``service.api.auth``), passed explicitly.

Routes (version 1; OpenAPI at ``/docs``):

- ``WS  /v1/stream``, ``GET /v1/positions``: ``routes.stream``;
- ``GET /v1/health``, ``/v1/config``, ``/v1/settings/schema``: ``routes.health``;
- ``GET /v1/cameras/{k}/snapshot.jpg`` (403 under ``privacy: positions_only``),
  ``/v1/cameras/{k}/boxes``, ``POST /v1/alignment/reset``: ``routes.cameras``;
- ``POST /v1/model/reload``: ``routes.model``; ``GET /metrics``: ``routes.metrics``;
- ``/v1/zones``, ``WS /v1/events``, ``/v1/mqtt/...``: ``routes.zones``;
- ``/v1/setup/...``: ``routes.setup``; ``GET /``, ``/setup``, ``/web/*``: ``routes.pages``.

Authentication (``service.api.auth``): with a token configured, every ``/v1`` route and
``/metrics`` needs it. Open without a token: ``/``, ``/setup``, ``/web/*`` (pages and scripts,
no data), ``/docs`` and ``/openapi.json`` (the API's shape, no data). Before any of it, the
request guard (``service.api.request_guard``) checks Host, Origin and bodies of every request.

Errors: every error body is ``service.api.errors.ErrorBody``, declared in OpenAPI per route.
"""

from __future__ import annotations

from fastapi import FastAPI

from service.api.auth import TokenCheck
from service.api.errors import install_error_handlers
from service.api.lifespan import daemon_lifespan
from service.api.request_guard import RequestGuard
from service.api.routes.cameras import cameras_router
from service.api.routes.health import health_router
from service.api.routes.metrics import metrics_router
from service.api.routes.model import model_router
from service.api.routes.pages import mount_pages, pages_router
from service.api.routes.setup import setup_router
from service.api.routes.stream import stream_router
from service.api.routes.zones import zones_router
from service.api.state import Daemon

ROUTERS = (
    setup_router,
    zones_router,
    stream_router,
    health_router,
    cameras_router,
    model_router,
    metrics_router,
)


def create_app(daemon: Daemon, *, manage_pipeline: bool = True) -> FastAPI:
    """Build the ASGI app; with ``manage_pipeline`` the lifespan starts and stops the pipeline."""
    app = FastAPI(
        title="MoM Localizer",
        version="1",
        description="Calibration-free human localization: live positions from cheap webcams.",
        lifespan=daemon_lifespan(daemon, manage_pipeline),
    )
    install_error_handlers(app)
    app.add_middleware(
        RequestGuard,
        bind_host=daemon.bind_host,
        allowed_hosts=daemon.allowed_hosts,
        allowed_origins=daemon.allowed_origins,
        routes=app.router.routes,  # the live list: the guard sees the routes included below
    )
    mount_pages(app)
    app.include_router(pages_router())
    token = TokenCheck(daemon.token)
    for router in ROUTERS:
        app.include_router(router(daemon, token))
    return app
