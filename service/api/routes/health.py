"""What the daemon is and how it does: ``GET /v1/health`` (cameras, model, pipeline, clients),
``GET /v1/config`` (what the map page needs: floor extent, camera names, stream rate) and
``GET /v1/settings/schema`` (every setting with its type, bounds and description)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from service.api.auth import TokenCheck
from service.api.errors import error_responses
from service.api.state import Daemon


def health_router(daemon: Daemon, token: TokenCheck) -> APIRouter:
    router = APIRouter(dependencies=token.secured, responses=error_responses(401, 403))

    @router.get("/v1/health", summary="Cameras, model, pipeline, clients")
    def health() -> dict[str, Any]:
        return daemon.health()

    @router.get("/v1/config", summary="Map extent, cameras, stream rate")
    def config() -> dict[str, Any]:
        return daemon.public_config()

    @router.get("/v1/settings/schema", summary="JSON schema of the settings file (documented)")
    def settings_schema() -> dict[str, Any]:
        from service.settings import Settings

        return Settings.model_json_schema()

    return router
