"""REST endpoints of the web set-up flow (``/setup`` page): record, train, verify.

- ``POST /v1/setup/start`` / ``stop``: a guided collection at floor marks;
  ``POST /v1/setup/record-again`` ``{"mark": "B2"}``: forget one mark's rows and record it alone.
- ``POST /v1/setup/train`` (202) / ``train/cancel``: ``momloc train`` in a child process (with
  the adaptive schedule a quick first model is loaded first, then the final one).
- ``POST /v1/setup/verify`` / ``verify/stop``: the check step (live error at a few marks).
- ``GET /v1/setup/status``: all of it, plus what each camera's detector sees now.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Body, HTTPException
from fastapi.responses import JSONResponse
from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from common.errors import MomlocError
from service.api.auth import TokenCheck
from service.api.errors import error_responses
from service.api.state import Daemon
from service.setup.marks import MAX_MARKS, MarkIn, grid_marks, marks_from_entries
from service.setup.session import SAFE_RECORDING_NAME, SetupSession
from service.setup.steps import SetupConflict
from service.setup.training import TrainingJob
from service.setup.verify import Verifier

# The schema's form of session.SAFE_RECORDING_NAME (JSON Schema's $ is the end of the text).
# Declared in the schema, checked by plain_npz: pydantic's own pattern message shows the regex.
RECORDING_NAME = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,80}\.npz$"


def plain_npz(name: str | None) -> str | None:
    """A recording name: a plain file name in the data directory, ending in .npz."""
    if name is not None and not SAFE_RECORDING_NAME.fullmatch(name):
        raise ValueError("use a plain file name ending in .npz (letters, digits, '.', '_', '-')")
    return name


_GRID = r"^\s*[0-9]{1,6}\s*[xX×]\s*[0-9]{1,6}\s*$"
_ROOM = r"^\s*[0-9]{1,6}(\.[0-9]{1,6})?\s*[xX×]\s*[0-9]{1,6}(\.[0-9]{1,6})?\s*$"


class StartRequest(BaseModel):
    """Either ``marks`` or ``grid`` + ``room``."""

    model_config = ConfigDict(
        extra="forbid",
        strict=True,  # a number where a number is meant: no true, no "5" (issue 25)
        # the either-or in the schema too, so /docs and schema-driven clients know it
        json_schema_extra={"anyOf": [{"required": ["marks"]}, {"required": ["grid", "room"]}]},
    )
    marks: list[MarkIn] | None = Field(
        None,
        min_length=1,
        max_length=MAX_MARKS,
        description=f"Explicit floor marks (1 to {MAX_MARKS}).",
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
    out: Annotated[str, AfterValidator(plain_npz)] = Field(
        "setup.npz",
        max_length=90,
        json_schema_extra={"pattern": RECORDING_NAME},
        description="File name in the daemon's data directory (a plain name ending in .npz).",
    )


class StopRequest(BaseModel):
    """No parameters: a JSON object ``{}`` (state changes take JSON bodies, see request_guard)."""

    model_config = ConfigDict(extra="forbid", strict=True)


class TrainRequest(BaseModel):
    """Every field optional (``{}``: the last recording, the adaptive schedule); the body itself
    is required, like every state change's (a body-less POST may be a cross-site form)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    recording: Annotated[str | None, AfterValidator(plain_npz)] = Field(
        None,
        max_length=90,
        json_schema_extra={"pattern": RECORDING_NAME},
        description="Recording file name in the daemon's data directory; default: the last one.",
    )
    epochs: int | None = Field(
        None, ge=1, le=2000, description="Maximum epochs (default: adaptive, a few minutes)."
    )
    first_model: bool | None = Field(
        None,
        description="Train and load a quick first model (seconds) before the final one; "
        "default: yes with the adaptive schedule, no with explicit epochs.",
    )


class RecordAgainRequest(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    mark: str = Field(min_length=1, max_length=40, description="Name of the mark, e.g. B2.")


class VerifyRequest(BaseModel):
    """Marks to check (default: up to four of the last recording's), and the timing."""

    model_config = ConfigDict(extra="forbid", strict=True)
    marks: list[MarkIn] | None = Field(
        None,
        min_length=1,
        max_length=MAX_MARKS,
        description="Marks to stand on; new ones are the best test.",
    )
    seconds: float = Field(5.0, gt=0, le=120, description="Seconds measured on each mark.")
    move_seconds: float = Field(5.0, ge=0, le=120, description="Time to reach each mark.")
    countdown: float = Field(2.0, ge=0, le=30, description="Seconds before measuring starts.")


VERIFY_DEFAULT_MARKS = 4


def setup_router(daemon: Daemon, token: TokenCheck) -> APIRouter:
    """The set-up routes; none when the daemon was built without the set-up flow's three parts
    (``service.daemon`` wires them; tests of other routes leave them out)."""
    router = APIRouter(
        prefix="/v1/setup",
        tags=["setup"],
        dependencies=token.secured,
        responses=error_responses(401, 403),
    )
    session, training, verifier = daemon.setup, daemon.training, daemon.verifier
    if session is None or training is None or verifier is None:
        return router

    def cameras_now() -> list[int]:
        """How many people each camera's detector sees in the newest frames."""
        return [len(daemon.pipeline.view(k).boxes) for k in range(len(daemon.camera_names))]

    def status() -> dict[str, Any]:
        return {
            **session.status(),
            "cameras_now": cameras_now(),
            "training": training.status(),
            "verify": verifier.status(),
        }

    _collection_routes(router, session, status)
    _training_routes(router, session, training)
    _check_routes(router, session, verifier)
    return router


def _collection_routes(
    router: APIRouter, session: SetupSession, status: Callable[[], dict[str, Any]]
) -> None:
    """Record at floor marks: start, status (of every step), record one mark again, stop."""

    @router.post(
        "/start",
        summary="Start a guided collection at floor marks",
        responses=error_responses(400, 409, 413, 415, 422),
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
            raise refused(error) from None

    router.get("/status", summary="Collection, training and check; what each camera sees")(status)

    @router.post(
        "/record-again",
        summary="Forget one mark's frames in the last recording and record that mark again",
        responses=error_responses(400, 409, 413, 415, 422),
    )
    def record_again(request: Annotated[RecordAgainRequest, Body()]) -> dict[str, Any]:
        try:
            return session.record_again(request.mark)
        except MomlocError as error:
            raise refused(error) from None

    @router.post(
        "/stop",
        summary="Stop the collection, keeping what was recorded",
        responses=error_responses(400, 413, 415, 422),
    )
    def stop(body: Annotated[StopRequest, Body()]) -> dict[str, Any]:
        return session.stop()


def _training_routes(router: APIRouter, session: SetupSession, training: TrainingJob) -> None:
    """Train a model on a recording in a child process, or cancel it."""

    @router.post(
        "/train",
        status_code=202,
        summary="Train a model on a recording (background process; follow it in /status)",
        responses=error_responses(400, 409, 413, 415, 422),
    )
    def train(body: Annotated[TrainRequest, Body()]) -> JSONResponse:
        try:
            if body.recording is not None:
                recording = session.data_dir / body.recording  # a plain name (plain_npz)
            elif session.last_recording is not None:
                recording = session.last_recording
            else:
                recording = session.data_dir / "setup.npz"
            started = training.start(Path(recording), body.epochs, body.first_model)
            return JSONResponse(started, status_code=202)
        except MomlocError as error:
            raise refused(error) from None

    @router.post(
        "/train/cancel",
        summary="Stop the running training (the served model stays)",
        responses=error_responses(400, 413, 415, 422),
    )
    def cancel_training(body: Annotated[StopRequest, Body()]) -> dict[str, Any]:
        return training.cancel()


def _check_routes(router: APIRouter, session: SetupSession, verifier: Verifier) -> None:
    """The check step: live error at a few marks."""

    @router.post(
        "/verify",
        summary="Check the served model: stand on marks, see the error at each",
        responses=error_responses(400, 409, 413, 415, 422),
    )
    def verify(request: Annotated[VerifyRequest, Body()]) -> dict[str, Any]:
        try:
            if request.marks:
                marks = marks_from_entries(request.marks, "marks")
            else:
                marks = spread(session.marks(), VERIFY_DEFAULT_MARKS)
            return verifier.start(marks, request.seconds, request.move_seconds, request.countdown)
        except MomlocError as error:
            raise refused(error) from None

    @router.post(
        "/verify/stop", summary="Stop the check", responses=error_responses(400, 413, 415, 422)
    )
    def stop_verify(body: Annotated[StopRequest, Body()]) -> dict[str, Any]:
        return verifier.stop()


def refused(error: MomlocError) -> HTTPException:
    """409 when the request conflicts with the set-up's state (a step runs, the marks are all
    recorded), 422 when the request itself is wrong."""
    return HTTPException(409 if isinstance(error, SetupConflict) else 422, str(error))


def spread(marks: list[Any], count: int) -> list[Any]:
    """Up to ``count`` marks evenly spread along the recording order (which covers the room)."""
    if len(marks) <= count:
        return list(marks)
    step = (len(marks) - 1) / (count - 1)
    return [marks[round(i * step)] for i in range(count)]
