"""The demo as it plays (issue 27), through the real server: the person on the sofa is served
seated, with one id, and the lounge zone around the sofa never empties while the others walk.

Lock-step rig (scene time, every frame set processed: no dependence on the machine's load), the
simulator's boxes, the shipped demo model (its set-up area's height model gives the posture:
expected to fail, strictly, while the shipped model predates the set-up area).
Clients are real: the WebSocket stream for the people and /v1/events for the zone.
"""

from __future__ import annotations

import asyncio
import collections
import json
from typing import Any

import numpy as np
import pytest
import websockets

from service.demo import DEMO_SCENE
from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(900)
SEAT = (7.0, 6.85)  # models.simulate.presets: the demo-lounge sitter's mid-hip
NEAR_M = 0.6
SNAPSHOTS = 300  # 10 s of the 30 fps scene
WARMUP = 60  # confirmation and the posture's 1 s average


def _run(srv: Any) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    async def collect() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        snapshots: list[dict[str, Any]] = []
        events: list[dict[str, Any]] = []
        async with (
            websockets.connect(srv.ws + "/v1/events") as event_ws,
            websockets.connect(srv.ws + "/v1/stream") as stream,
        ):

            async def listen() -> None:
                while True:
                    events.append(json.loads(await event_ws.recv()))

            listener = asyncio.ensure_future(listen())
            while len(snapshots) < SNAPSHOTS:
                snapshots.append(json.loads(await asyncio.wait_for(stream.recv(), 120)))
            listener.cancel()
        return snapshots, events

    return asyncio.run(collect())


def test_the_demo_sitter_is_seated_and_keeps_the_lounge_occupied() -> None:
    with running_server(scene=DEMO_SCENE, lockstep=True) as srv:
        snapshots, events = _run(srv)
        zone = {z["name"]: z for z in srv.get("/v1/zones").json()["zones"]}["lounge"]
    near = [
        [p for p in message["people"] if np.hypot(p["x"] - SEAT[0], p["y"] - SEAT[1]) < NEAR_M]
        for message in snapshots[WARMUP:]
    ]
    # the sitter: whoever is near the seat most often (walkers pass by the sofa now and then)
    ids = collections.Counter(p["id"] for people in near for p in people)
    sitter = ids.most_common(1)[0][0]
    served = [p for people in near for p in people if p["id"] == sitter]
    assert len(served) >= 0.98 * len(near), (len(served), ids)  # one id, there all the time
    seated = [p.get("posture") == "sitting" for p in served]
    assert np.mean(seated) >= 0.95, [p.get("posture") for p in served]
    assert all(0.5 <= p["posture_confidence"] <= 1.0 for p in served)
    lounge = [e for e in events if e.get("zone") == "lounge"]
    entered = [e["type"] == "enter" and e["id"] == served[0]["id"] for e in lounge]
    assert any(entered), lounge
    since = lounge[entered.index(True) :]
    assert all(e["count"] >= 1 for e in since), since  # never empty once the sitter is in
    assert served[0]["id"] in zone["ids"] and zone["count"] >= 1
