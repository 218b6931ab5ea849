"""``GET /metrics``: Prometheus text (the families: ``service.api.metrics``)."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import PlainTextResponse

from service.api.auth import TokenCheck
from service.api.errors import error_responses
from service.api.metrics import metrics_text
from service.api.state import Daemon


def metrics_router(daemon: Daemon, token: TokenCheck) -> APIRouter:
    router = APIRouter()

    @router.get(
        "/metrics",
        dependencies=token.secured,
        response_class=PlainTextResponse,
        responses={
            200: {"content": {"text/plain": {}}, "description": "Prometheus text"},
            **error_responses(401, 403, plain_route=True),
        },
        summary="Prometheus metrics",
    )
    def metrics() -> PlainTextResponse:
        body, content_type = metrics_text(daemon)
        return PlainTextResponse(body, media_type=content_type)

    return router
