"""REST endpoints of the web set-up flow (``/setup`` page): start, follow and stop a collection."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, HTTPException
from pydantic import BaseModel, ConfigDict, Field

from models.errors import MomlocError
from service.api_errors import error_responses
from service.setup.marks import MAX_MARKS, MarkIn, grid_marks, marks_from_entries
from service.setup.session import SetupSession

_GRID = r"^\s*[0-9]{1,6}\s*[xX×]\s*[0-9]{1,6}\s*$"
_ROOM = r"^\s*[0-9]{1,6}(\.[0-9]{1,6})?\s*[xX×]\s*[0-9]{1,6}(\.[0-9]{1,6})?\s*$"


class StartRequest(BaseModel):
    """Either ``marks`` or ``grid`` + ``room``."""

    model_config = ConfigDict(
        extra="forbid",
        # the either-or in the schema too, so /docs and schema-driven clients know it
        json_schema_extra={"anyOf": [{"required": ["marks"]}, {"required": ["grid", "room"]}]},
    )
    marks: list[MarkIn] | None = Field(
        None, max_length=MAX_MARKS, description=f"Explicit floor marks (at most {MAX_MARKS})."
    )
    grid: str | None = Field(
        None, max_length=32, pattern=_GRID, description="Grid of marks RxC, e.g. 3x3."
    )
    room: str | None = Field(
        None, max_length=32, pattern=_ROOM, description="Room WxD in metres, for grid."
    )
    seconds: float = Field(20.0, gt=0, le=600, description="Seconds recorded on each mark.")
    walk: bool = Field(False, description="Also record walks between marks (interpolated).")
    countdown: float = Field(3.0, ge=0, le=30, description="Seconds before recording starts.")
    move_seconds: float = Field(5.0, ge=0, le=120, description="Time to reach each mark.")
    out: str = Field(
        "setup.npz", max_length=90, description="File name in the daemon's data directory."
    )


class StopRequest(BaseModel):
    """No parameters: a JSON object ``{}`` (state changes take JSON bodies, see request_guard)."""

    model_config = ConfigDict(extra="forbid")


def create_setup_router(session: SetupSession) -> APIRouter:
    router = APIRouter(prefix="/v1/setup", tags=["setup"])

    @router.post(
        "/start",
        summary="Start a guided collection at floor marks",
        responses=error_responses(409, 413, 415, 422),
    )
    def start(request: Annotated[StartRequest, Body()]) -> dict[str, Any]:
        try:
            if request.marks:
                marks = marks_from_entries(request.marks, "marks")
            elif request.grid and request.room:
                marks = grid_marks(request.grid, request.room)
            else:
                raise MomlocError("give either marks, or grid and room")
            return session.start(
                marks,
                request.seconds,
                request.out,
                walk=request.walk,
                countdown_s=request.countdown,
                move_s=request.move_seconds,
            )
        except MomlocError as error:
            raise HTTPException(409 if "already" in str(error) else 422, str(error)) from None

    @router.get("/status", summary="Progress of the current or last collection")
    def status() -> dict[str, Any]:
        return session.status()

    @router.post(
        "/stop",
        summary="Stop the collection, keeping what was recorded",
        responses=error_responses(413, 415, 422),
    )
    def stop(body: Annotated[StopRequest, Body()]) -> dict[str, Any]:
        return session.stop()

    return router
