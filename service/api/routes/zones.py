"""Zone and MQTT routes.

- ``GET  /v1/zones`` polygons, current occupancy (count, ids), the fall state and the last events.
- ``WS   /v1/events`` one enter/leave or fall event JSON per message (schemas in
  ``service.outputs.zones``, ``service.outputs.falls``);
  a client that falls 1000 events behind loses the oldest (see ``service.outputs.zone_monitor``).
- ``POST /v1/mqtt/discovery/remove`` ``{}`` deletes this room's Home Assistant entities.

The outputs start and stop with the app (``service.api.lifespan``). Authentication:
``service.api.auth``; the WebSocket is accepted and closed with 4401 on a wrong token.
"""

from __future__ import annotations

import contextlib
from typing import Annotated, Any

from fastapi import APIRouter, Body, HTTPException, WebSocket

from service.api.auth import WS_AUTH_CLOSE, TokenCheck
from service.api.errors import error_responses
from service.api.request_guard import EmptyBody
from service.api.state import Daemon
from service.api.websocket_tasks import run_until_either


def zones_router(daemon: Daemon, token: TokenCheck) -> APIRouter:
    outputs = daemon.outputs
    # 400: a body that is not text (invalid UTF-8), which FastAPI refuses before validation
    router = APIRouter(responses=error_responses(400, 401, 403, 409, 413, 415, 422, 503))
    secured = token.secured

    @router.get(
        "/v1/zones", dependencies=secured, summary="Zones: polygons, occupancy, falls, events"
    )
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
        if not token.allows(websocket.headers, websocket.query_params):
            await websocket.close(WS_AUTH_CLOSE, "missing or wrong token")
            return
        if outputs is None:
            await websocket.close(1000, "no zones")
            return
        subscription = outputs.zones.events.subscribe()

        async def sender() -> None:
            while True:
                await websocket.send_text(await subscription.next())

        try:
            await run_until_either(sender(), websocket)
        finally:
            outputs.zones.events.unsubscribe(subscription)
            with contextlib.suppress(Exception):
                await websocket.close()

    return router
