"""Zones over the daemon's own API (no MQTT): /v1/zones, WS /v1/events, token checks."""

from __future__ import annotations

import asyncio
import json

import pytest
import websockets

from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(300)


def test_zone_routes_need_the_token_and_serve_the_demo_zones():
    with running_server(token="zone-token") as srv:
        assert srv.get("/v1/zones", headers={"Authorization": "Bearer wrong"}).status_code == 401
        body = srv.get("/v1/zones").json()
        assert [z["name"] for z in body["zones"]] == ["kitchen", "lounge"]
        assert all({"polygon", "count", "ids", "hold_s"} <= set(z) for z in body["zones"])
        assert srv.get("/v1/config").json()["zones"][1]["name"] == "lounge"
        assert srv.get("/v1/health").json()["zones"]["zones"] == 2

        async def closed_code() -> int:
            async with websockets.connect(srv.ws + "/v1/events?token=wrong") as ws:
                with pytest.raises(websockets.ConnectionClosed) as closed:
                    await ws.recv()
                assert closed.value.rcvd is not None
                return closed.value.rcvd.code

        assert asyncio.run(closed_code()) == 4401


def test_events_stream_matches_the_occupancy(monkeypatch):
    monkeypatch.setenv(
        "MOMLOC_ZONES",
        json.dumps([{"name": "all", "polygon": [[-1, -1], [11, -1], [11, 11], [-1, 11]]}]),
    )
    with running_server(people=2) as srv:

        async def first_events(n: int) -> list[dict]:
            async with websockets.connect(srv.ws + "/v1/events") as ws:
                return [json.loads(await asyncio.wait_for(ws.recv(), 60)) for _ in range(n)]

        events = asyncio.run(first_events(2))
        assert [e["type"] for e in events] == ["enter", "enter"]
        assert events[1]["count"] == 2 and sorted(events[1]["ids"]) == sorted(
            e["id"] for e in events
        )
        zone = srv.get("/v1/zones").json()["zones"][0]
        assert zone["name"] == "all" and zone["count"] >= 1
