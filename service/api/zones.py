"""Zone and MQTT routes, and the MQTT link's start/stop with the app.

- ``GET  /v1/zones`` polygons, current occupancy (count, ids) and the last events.
- ``WS   /v1/events`` one enter/leave event JSON per message (schema in ``service.outputs.zones``);
  a client that falls 1000 events behind loses the oldest (see ``service.outputs.zone_monitor``).
- ``POST /v1/mqtt/discovery/remove`` ``{}`` deletes this room's Home Assistant entities.

The router carries its own lifespan (FastAPI merges it into the app's, inside it): the MQTT
publisher connects after the pipeline has started and publishes ``offline`` before it stops.
Authentication follows ``service.api.app``: with a token set, ``Authorization: Bearer`` or
``?token=``; the WebSocket is accepted and closed with 4401 on a wrong token.
"""

from __future__ import annotations

import asyncio
import contextlib
import secrets
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Annotated, Any

from fastapi import (
    APIRouter,
    Body,
    Depends,
    HTTPException,
    Request,
    WebSocket,
    WebSocketDisconnect,
)

from service.api.request_guard import EmptyBody

WS_AUTH_CLOSE = 4401


def _authorized(expected: str | None, headers: Any, query: Any) -> bool:
    if expected is None:
        return True
    auth = headers.get("authorization", "")
    given = auth[7:].strip() if auth.lower().startswith("bearer ") else query.get("token")
    return given is not None and secrets.compare_digest(given.encode(), expected.encode())


@asynccontextmanager
async def outputs_running(outputs: Any) -> AsyncIterator[None]:
    """Start the publishers (MQTT, OSC) and zone events with the app, stop them with it.

    Entered by the app's own lifespan, not given to ``APIRouter(lifespan=...)``: FastAPI
    releases before 0.112 (our floor is 0.110) never run a router's lifespan, so MQTT would
    silently never connect there (found by ``make test-floors``).
    """
    if outputs is None:
        yield
        return
    outputs.zones.events.bind(asyncio.get_running_loop())
    if outputs.mqtt is not None:
        await asyncio.to_thread(outputs.mqtt.start)
    if getattr(outputs, "osc", None) is not None:
        outputs.osc.start()
    try:
        yield
    finally:
        if getattr(outputs, "osc", None) is not None:
            await asyncio.to_thread(outputs.osc.stop)
        if outputs.mqtt is not None:
            await asyncio.to_thread(outputs.mqtt.stop)
        outputs.zones.events.bind(None)


def create_zones_router(daemon: Any) -> APIRouter:
    outputs = daemon.outputs

    def require_token(request: Request) -> None:
        if not _authorized(daemon.token, request.headers, request.query_params):
            raise HTTPException(401, "missing or wrong token", {"WWW-Authenticate": "Bearer"})

    router = APIRouter()
    secured = [Depends(require_token)]

    @router.get("/v1/zones", dependencies=secured, summary="Zones: polygons, occupancy, events")
    def zones() -> dict[str, Any]:
        if outputs is None:
            return {"v": 1, "t": None, "zones": [], "recent_events": []}
        return outputs.zones.describe()

    @router.post(
        "/v1/mqtt/discovery/remove",
        dependencies=secured,
        summary="Remove this room's Home Assistant entities (empty retained configs)",
    )
    def remove_discovery(body: Annotated[EmptyBody, Body()]) -> dict[str, Any]:
        if outputs is None or outputs.mqtt is None:
            raise HTTPException(409, "mqtt is not configured")
        if not outputs.mqtt.connected:
            raise HTTPException(503, "not connected to the MQTT broker")
        return {"removed": outputs.remove_discovery()}

    @router.websocket("/v1/events")
    async def events(websocket: WebSocket) -> None:
        await websocket.accept()
        if not _authorized(daemon.token, websocket.headers, websocket.query_params):
            await websocket.close(WS_AUTH_CLOSE, "missing or wrong token")
            return
        if outputs is None:
            await websocket.close(1000, "no zones")
            return
        subscription = outputs.zones.events.subscribe()

        async def sender() -> None:
            while True:
                await websocket.send_text(await subscription.next())

        async def receiver() -> None:
            while (await websocket.receive())["type"] != "websocket.disconnect":
                pass

        tasks = [asyncio.create_task(sender()), asyncio.create_task(receiver())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, Exception):
                    await task
            outputs.zones.events.unsubscribe(subscription)
            with contextlib.suppress(Exception):
                await websocket.close()

    return router
