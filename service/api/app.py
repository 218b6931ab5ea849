"""HTTP and WebSocket API (FastAPI): stream, positions, health, camera snapshots, metrics, map.

Routes (version 1; OpenAPI at ``/docs``):

- ``WS  /v1/stream?rate=HZ`` one snapshot JSON per message (see ``service.pipeline.hub``), at most
  ``rate`` per second (default and ceiling: ``stream.rate``). Protocol pings keep idle links alive.
- ``GET /v1/positions`` newest snapshot; ``GET /v1/health`` cameras, model, pipeline, clients.
- ``GET /v1/cameras/{k}/snapshot.jpg`` newest frame of camera k with boxes and track ids drawn.
- ``GET /v1/config`` what the map page needs (floor extent, camera names, stream rate).
- ``GET /v1/settings/schema`` every setting with its type, bounds and description.
- ``POST /v1/model/reload`` hot-swap the MoM model (refused if it does not fit the cameras).
- ``GET /metrics`` Prometheus text; ``GET /`` the live map.

Authentication: with a token configured, every ``/v1`` route and ``/metrics`` needs it, as
``Authorization: Bearer TOKEN`` or ``?token=TOKEN`` (browsers cannot set WebSocket headers).
Open without a token: ``/``, ``/setup``, ``/web/*`` (pages and scripts, no data), ``/docs`` and
``/openapi.json`` (the API's shape, no data). REST answers 401; the WebSocket is accepted and
closed with code 4401 so that clients can tell an auth failure from a network error.

Order of checks on the WebSocket: Host and Origin (``service.api.request_guard``: a foreign page's
handshake is refused with 403 before anything else), then the token (4401), then ``rate``: a
malformed one is accepted and closed with 4400 and the reason (uvicorn's sans-I/O WebSocket logs
an ERROR for every denial response, which would let anyone fill the log).

Errors: every error body is ``service.api.errors.ErrorBody``, declared in OpenAPI per route.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import secrets
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Annotated, Any

from fastapi import (
    Body,
    Depends,
    FastAPI,
    HTTPException,
    Query,
    Request,
    WebSocket,
    WebSocketDisconnect,
)
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field

from common.errors import MomlocError
from service.api.errors import error_response, error_responses, install_error_handlers
from service.api.metrics import metrics_text
from service.api.request_guard import EmptyBody, RequestGuard
from service.api.setup_routes import create_setup_router
from service.api.snapshot_image import render_camera_jpeg
from service.api.state import Daemon
from service.api.zones import create_zones_router, outputs_running
from service.snapshot import SnapshotBody

WEB_DIR = Path(__file__).resolve().parent / "web"
WS_AUTH_CLOSE = 4401
WS_BAD_REQUEST_CLOSE = 4400


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


def _token_of(request_headers: Any, query: Any) -> str | None:
    auth = request_headers.get("authorization", "")
    if auth.lower().startswith("bearer "):
        return auth[7:].strip()
    return query.get("token")


def create_app(daemon: Daemon, *, manage_pipeline: bool = True) -> FastAPI:
    """Build the ASGI app; with ``manage_pipeline`` the lifespan starts and stops the pipeline."""
    expected = daemon.token

    def authorized(headers: Any, query: Any) -> bool:
        if expected is None:
            return True
        given = _token_of(headers, query)
        return given is not None and secrets.compare_digest(given.encode(), expected.encode())

    def require_token(request: Request) -> None:
        if not authorized(request.headers, request.query_params):
            raise HTTPException(401, "missing or wrong token", {"WWW-Authenticate": "Bearer"})

    @asynccontextmanager
    async def lifespan(app: FastAPI):  # type: ignore[no-untyped-def]
        daemon.hub.bind(asyncio.get_running_loop())
        if manage_pipeline:
            await asyncio.to_thread(daemon.pipeline.start)
        if daemon.watcher is not None:
            daemon.watcher.start()
        try:
            async with outputs_running(daemon.outputs):
                yield
        finally:
            if daemon.watcher is not None:
                daemon.watcher.stop()
            if daemon.setup is not None:
                await asyncio.to_thread(daemon.setup.stop)
            if daemon.training is not None:
                await asyncio.to_thread(daemon.training.cancel)  # no orphan child process
            if daemon.verifier is not None:
                await asyncio.to_thread(daemon.verifier.stop)
            if manage_pipeline:
                await asyncio.to_thread(daemon.pipeline.stop)
            daemon.hub.bind(None)

    app = FastAPI(
        title="MoM Localizer",
        version="1",
        description="Calibration-free human localization: live positions from cheap webcams.",
        lifespan=lifespan,
    )
    install_error_handlers(app)
    app.add_middleware(
        RequestGuard,
        bind_host=daemon.bind_host,
        allowed_hosts=daemon.allowed_hosts,
        allowed_origins=daemon.allowed_origins,
        routes=app.router.routes,
    )
    secured = [Depends(require_token)]
    auth = error_responses(401, 403)
    # 400: a body that is not text (invalid UTF-8), which FastAPI refuses before validation
    change = error_responses(400, 401, 403, 413, 415, 422)
    app.mount("/web", StaticFiles(directory=WEB_DIR), name="web")

    @app.get("/", include_in_schema=False)
    def index() -> FileResponse:
        return FileResponse(WEB_DIR / "index.html", headers={"Cache-Control": "no-cache"})

    @app.get("/setup", include_in_schema=False)
    def setup_page() -> FileResponse:
        return FileResponse(WEB_DIR / "setup.html", headers={"Cache-Control": "no-cache"})

    # service.daemon wires the set-up flow's three parts together; a Daemon built without them
    # (tests of other routes) has no /v1/setup routes
    setup, training, verifier = daemon.setup, daemon.training, daemon.verifier
    if setup is not None and training is not None and verifier is not None:
        router = create_setup_router(
            setup,
            training,
            verifier,
            lambda: [len(daemon.pipeline.view(k).boxes) for k in range(len(daemon.camera_names))],
        )
        app.include_router(router, dependencies=secured, responses=auth)
    # zones, events, MQTT (own auth, lifespan); the guard covers its WebSocket and POST too
    app.include_router(
        create_zones_router(daemon),
        responses=error_responses(400, 401, 403, 409, 413, 415, 422, 503),
    )

    @app.get(
        "/v1/positions",
        dependencies=secured,
        responses=auth,
        summary="Newest snapshot",
        response_model=SnapshotBody,  # the schema /docs shows; the body is the hub's own text
    )
    def positions() -> Response:
        return Response(daemon.hub.latest().text, media_type="application/json")

    @app.get(
        "/v1/health",
        dependencies=secured,
        responses=auth,
        summary="Cameras, model, pipeline, clients",
    )
    def health() -> dict[str, Any]:
        return daemon.health()

    @app.get(
        "/v1/config",
        dependencies=secured,
        responses=auth,
        summary="Map extent, cameras, stream rate",
    )
    def config() -> dict[str, Any]:
        return daemon.public_config()

    @app.get(
        "/v1/settings/schema",
        dependencies=secured,
        responses=auth,
        summary="JSON schema of the settings file (documented)",
    )
    def settings_schema() -> dict[str, Any]:
        from service.settings import Settings

        return Settings.model_json_schema()

    @app.get(
        "/v1/cameras/{k}/snapshot.jpg",
        dependencies=secured,
        summary="Newest frame of camera k with boxes and ids",
        response_class=Response,
        responses={
            200: {"content": {"image/jpeg": {}}, "description": "JPEG image"},
            **error_responses(401, 403, 404, 422, 503, plain_route=True),
        },
    )
    def snapshot_jpg(
        k: Annotated[int, PathParam(ge=0, le=8, description="Camera index")],
        quality: Annotated[int, Query(ge=10, le=100, description="JPEG quality")] = 75,
        width: Annotated[int | None, Query(ge=32, le=4096, description="Resize width")] = None,
    ) -> Response:
        if k >= daemon.pipeline.num_cameras:
            raise HTTPException(
                404, f"no camera {k}; cameras are 0..{daemon.pipeline.num_cameras - 1}"
            )
        data = render_camera_jpeg(daemon.pipeline.view(k), quality=quality, width=width)
        if data is None:
            raise HTTPException(503, f"camera {k} has not delivered a frame yet")
        return Response(data, media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    @app.post(
        "/v1/model/reload",
        dependencies=secured,
        responses={**change, **error_responses(409)},
        summary="Hot-swap the MoM model",
    )
    def reload_model(body: Annotated[ReloadRequest, Body()]) -> JSONResponse:
        try:
            info = daemon.pipeline.reload_model(body.model_dir)
        except MomlocError as error:
            return error_response(409, str(error))
        return JSONResponse(info)

    @app.post(
        "/v1/alignment/reset",
        dependencies=secured,
        responses=change,
        summary="Accept the cameras where they are now (new references, clears camera-moved)",
    )
    def reset_alignment(body: Annotated[EmptyBody, Body()]) -> dict[str, Any]:
        daemon.pipeline.reset_alignment()
        return {"cameras": [c["alignment"] for c in daemon.camera_states()]}

    @app.get(
        "/metrics",
        dependencies=secured,
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

    @app.websocket("/v1/stream")
    async def stream(websocket: WebSocket) -> None:
        if not authorized(websocket.headers, websocket.query_params):
            await websocket.accept()
            await websocket.close(WS_AUTH_CLOSE, "missing or wrong token")
            return
        rate = _parse_rate(websocket.query_params.get("rate"), daemon.stream_rate)
        await websocket.accept()
        if rate is None:
            reason = "rate must be a number of snapshots per second > 0"
            await websocket.close(WS_BAD_REQUEST_CLOSE, reason)
            return
        await _serve_stream(websocket, daemon, rate)

    return app


def _parse_rate(raw: str | None, ceiling: float) -> float | None:
    """``rate`` query value clamped to the configured ceiling; None when malformed."""
    if raw is None:
        return ceiling
    try:
        rate = float(raw)
    except ValueError:
        return None
    if not math.isfinite(rate) or rate <= 0:
        return None
    return min(rate, ceiling)


async def _serve_stream(websocket: WebSocket, daemon: Daemon, rate: float) -> None:
    """Send from the client's latest-value slot, never faster than ``rate`` on average.

    The schedule lets one message through at once after an idle spell (a bucket of two), so a
    client asking for the pipeline's own rate does not lose snapshots to timing jitter.
    """
    subscription = daemon.hub.subscribe()
    interval = 1.0 / rate
    loop = asyncio.get_running_loop()

    async def sender() -> None:
        next_time = 0.0
        while True:
            snapshot = await subscription.next()
            delay = next_time - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
                snapshot = _newest(subscription, snapshot)
            daemon.hub.note_send(snapshot.seq)
            await websocket.send_text(snapshot.text)
            next_time = max(next_time + interval, loop.time())

    async def receiver() -> None:  # notices a closed client even when nothing is being sent
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return

    tasks = [asyncio.create_task(sender()), asyncio.create_task(receiver())]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, Exception):
                await task
        daemon.hub.unsubscribe(subscription)
        with contextlib.suppress(Exception):
            await websocket.close()


def _newest(subscription: Any, fallback: Any) -> Any:
    """After a rate-limit pause, take the value that arrived meanwhile (if any)."""
    value = subscription.take_nowait()
    if value is None:
        return fallback
    subscription.skipped += 1
    return value
