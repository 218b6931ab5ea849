"""The demo as it plays (issue 27), through the real server: the person on the sofa is served
seated, with one id, and the lounge zone around the sofa never empties while the others walk.

Lock-step rig (scene time, every frame set processed) and a fixed window of snapshots (seq
61-300, recorded by a hub tap from the first one): a loaded machine gets the very same figures.
(When the window was whatever 300 snapshots the WebSocket client happened to receive, it began
wherever the client connected in the scene, and the sitter was served in 224-240 of 240.) The
simulator's boxes, the shipped demo model (its set-up area's height model gives the posture).
Clients are real: the WebSocket stream is checked to carry those same snapshots, and
/v1/events gives the zone.
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
from tests.e2e.client_checks import Tap
from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(900)
SEAT = (7.0, 6.85)  # models.simulate.presets: the demo-lounge sitter's mid-hip
NEAR_M = 0.6
LAST_SEQ = 300  # 10 s of the 30 fps scene
WARMUP = 60  # confirmation and the posture's 1 s average
STREAMED = 30  # WebSocket messages compared with the tap at least


def _collect(srv: Any) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The stream's and the event route's messages until the pipeline is past the window."""

    async def collect() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        streamed: list[dict[str, Any]] = []
        events: list[dict[str, Any]] = []
        async with (
            websockets.connect(srv.ws + "/v1/events") as event_ws,
            websockets.connect(srv.ws + "/v1/stream") as stream,
        ):

            async def listen() -> None:
                while True:
                    events.append(json.loads(await event_ws.recv()))

            listener = asyncio.ensure_future(listen())
            while len(streamed) < STREAMED or streamed[-1]["seq"] < LAST_SEQ:
                streamed.append(json.loads(await asyncio.wait_for(stream.recv(), 120)))
            listener.cancel()
        return streamed, events

    return asyncio.run(collect())


def test_the_demo_sitter_is_seated_and_keeps_the_lounge_occupied() -> None:
    tap = Tap()
    with running_server(scene=DEMO_SCENE, lockstep=True, publishers=[tap]) as srv:
        streamed, events = _collect(srv)
        zone = {z["name"]: z for z in srv.get("/v1/zones").json()["zones"]}["lounge"]
    for message in streamed:
        assert message == tap.by_seq[message["seq"]].as_dict()  # clients get what was published
    window = [tap.by_seq[seq].as_dict() for seq in range(WARMUP + 1, LAST_SEQ + 1)]
    near = [
        [p for p in message["people"] if np.hypot(p["x"] - SEAT[0], p["y"] - SEAT[1]) < NEAR_M]
        for message in window
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
    # the client may connect after the sitter entered (the pipeline does not wait for it)
    entered = [e["type"] == "enter" and e["id"] == served[0]["id"] for e in lounge]
    since = lounge[entered.index(True) :] if any(entered) else lounge
    assert all(e["count"] >= 1 for e in since), since  # never empty once the sitter is in
    assert served[0]["id"] in zone["ids"] and zone["count"] >= 1
