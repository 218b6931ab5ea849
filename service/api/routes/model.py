"""``POST /v1/model/reload``: hot-swap the MoM model (refused with 409 if it does not fit the
cameras; the running model stays)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field

from common.errors import MomlocError
from service.api.auth import TokenCheck
from service.api.errors import error_response, error_responses
from service.api.state import Daemon


class ReloadRequest(BaseModel):
    """``{}`` reloads the current model. The body is required, like every state change's: a
    body-less POST may be a cross-site form (``service.api.request_guard`` answers it 415)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    model_dir: str | None = Field(
        None,
        min_length=1,
        max_length=4096,
        description="Model directory; default: the current one.",
    )


def model_router(daemon: Daemon, token: TokenCheck) -> APIRouter:
    router = APIRouter(dependencies=token.secured)

    @router.post(
        "/v1/model/reload",
        responses=error_responses(400, 401, 403, 409, 413, 415, 422),
        summary="Hot-swap the MoM model",
    )
    def reload_model(body: Annotated[ReloadRequest, Body()]) -> JSONResponse:
        try:
            info = daemon.pipeline.reload_model(body.model_dir)
        except MomlocError as error:
            return error_response(409, str(error))
        return JSONResponse(info)

    return router
