"""The positions: ``WS /v1/stream?rate=HZ`` (one snapshot JSON per message) and
``GET /v1/positions`` (the newest snapshot).

The stream sends at most ``rate`` snapshots per second (default and ceiling: ``stream.rate``);
protocol pings keep idle links alive. Order of checks on the WebSocket: Host and Origin
(``service.api.request_guard``: a foreign page's handshake is refused with 403 before anything
else), then the token (4401), then ``rate``: a malformed one is accepted and closed with 4400 and
the reason (uvicorn's sans-I/O WebSocket logs an ERROR for every denial response, which would let
anyone fill the log).
"""

from __future__ import annotations

import asyncio
import contextlib
import math

from fastapi import APIRouter, WebSocket
from fastapi.responses import Response

from service.api.auth import WS_AUTH_CLOSE, TokenCheck
from service.api.errors import error_responses
from service.api.state import Daemon
from service.api.websocket_tasks import run_until_either
from service.pipeline.hub import Subscription
from service.snapshot import Snapshot, SnapshotBody

WS_BAD_REQUEST_CLOSE = 4400


def stream_router(daemon: Daemon, token: TokenCheck) -> APIRouter:
    router = APIRouter()

    @router.get(
        "/v1/positions",
        dependencies=token.secured,
        responses=error_responses(401, 403),
        summary="Newest snapshot",
        response_model=SnapshotBody,  # the schema /docs shows; the body is the hub's own text
    )
    def positions() -> Response:
        return Response(daemon.hub.latest().text, media_type="application/json")

    @router.websocket("/v1/stream")
    async def stream(websocket: WebSocket) -> None:
        if not token.allows(websocket.headers, websocket.query_params):
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

    return router


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

    try:
        await run_until_either(sender(), websocket)
    finally:
        daemon.hub.unsubscribe(subscription)
        with contextlib.suppress(Exception):
            await websocket.close()


def _newest(subscription: Subscription, fallback: Snapshot) -> Snapshot:
    """After a rate-limit pause, take the value that arrived meanwhile (if any)."""
    value = subscription.take_nowait()
    if value is None:
        return fallback
    subscription.skipped += 1
    return value
