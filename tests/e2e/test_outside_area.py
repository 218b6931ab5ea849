"""The set-up area through the real daemon: people walking beyond the floor a model was set up on
are dropped by default, or served flagged (``tracking.outside_area: flag``) over the WebSocket and
REST while zones leave them out.

The model is set up on the left half of the demo room only (x < 5 m, simulated people walking
there); the served scene's people walk the whole 10 x 10 m room, so about half the time someone
stands beyond the set-up area, in view of both cameras.
"""

from __future__ import annotations

import asyncio
import functools
import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import websockets

from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(600)
SETUP_X = 5.0  # the model's labels: x below this
SNAPSHOTS = 240  # 8 s of the 30 fps scene


@functools.cache
def _left_half_model() -> Path:
    from models.mom.training.train import train_model
    from models.simulate import simulate

    data = simulate("indoor-2cam", frames=1200, seed=1, people=3).dataset
    left = np.flatnonzero(data.world[:, 0] < SETUP_X)
    out = Path(tempfile.mkdtemp(prefix="mom-e2e-area-")) / "left"
    train_model(data.subset(left), out, epochs=30, seed=0, progress=False)
    return out


def _stream(srv: Any, count: int) -> list[dict[str, Any]]:
    async def collect() -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        async with websockets.connect(srv.ws + "/v1/stream") as ws:
            while len(out) < count:
                out.append(json.loads(await ws.recv()))
        return out

    return asyncio.run(collect())


def _people(messages: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [p for m in messages for p in m["people"]]


def test_people_beyond_the_set_up_area_are_not_served_by_default() -> None:
    with running_server(model_dir=_left_half_model(), lockstep=True, people=4) as srv:
        people = _people(_stream(srv, SNAPSHOTS))
    assert len(people) > 100
    assert not any("outside" in p for p in people)
    xs = np.array([p["x"] for p in people])
    # the hull of the labels plus its 0.5 m margin; single-view range noise aside
    assert np.mean(xs > SETUP_X + 0.8) < 0.02


def test_flagged_people_are_served_marked_and_zones_leave_them_out(monkeypatch) -> None:
    monkeypatch.setenv("MOMLOC_TRACKING__OUTSIDE_AREA", "flag")
    room = [[-1, -1], [11, -1], [11, 11], [-1, 11]]
    monkeypatch.setenv("MOMLOC_ZONES", json.dumps([{"name": "room", "polygon": room, "hold_s": 0}]))
    with running_server(model_dir=_left_half_model(), lockstep=True, people=4) as srv:
        messages = _stream(srv, SNAPSHOTS)
        outside = [p for p in _people(messages) if p.get("outside")]
        inside = [p for p in _people(messages) if not p.get("outside")]
        assert len(outside) > 30 and len(inside) > 30
        assert np.median([p["x"] for p in outside]) > SETUP_X
        assert all(p["outside"] is True for p in outside)
        # frozen, the room zone holds exactly the newest snapshot's inside people
        srv.daemon.pipeline.stop()
        latest = srv.get("/v1/positions").json()
        zone = srv.get("/v1/zones").json()["zones"][0]
        assert set(zone["ids"]) == {p["id"] for p in latest["people"] if not p.get("outside")}
