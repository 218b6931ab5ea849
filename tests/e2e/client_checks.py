"""What the engine-client e2e tests (Unity under Mono, Godot headless) check the same way.

Each engine harness prints ``STATE {json}`` after a frame that applied a new snapshot (seq,
capture time, the engine position of every person object, how many objects exist) and
``STATUS {json}`` twice a second. A :class:`Tap` on the hub records every snapshot the daemon
published, and ``/v1/positions`` is checked against the same record, so "the client shows what
/v1/positions says" is checked seq by seq.
"""

from __future__ import annotations

import json
import time
from typing import Any

import pytest
from pydantic import TypeAdapter

from service.snapshot import Snapshot, SnapshotBody
from tests.e2e.server import RunningServer
from tests.e2e.toolchains import LineProcess

WIRE = TypeAdapter(SnapshotBody)  # the wire format's types (``service.snapshot``), strictly


class Tap:
    """A hub publisher keeping every snapshot by seq (test only)."""

    name = "test-tap"

    def __init__(self) -> None:
        self.by_seq: dict[int, Snapshot] = {}

    def offer(self, snapshot: Snapshot) -> None:
        self.by_seq[snapshot.seq] = snapshot

    def stats(self) -> dict[str, Any]:
        return {}


def states(lines: list[str]) -> list[dict[str, Any]]:
    return [json.loads(line[6:]) for line in lines if line.startswith("STATE ")]


def statuses(lines: list[str]) -> list[dict[str, Any]]:
    return [json.loads(line[7:]) for line in lines if line.startswith("STATUS ")]


def check_states_match(
    srv: RunningServer, client: LineProcess, tap: Tap, after: int, t_tolerance: float = 1e-6
) -> int:
    """Every client state for a recorded snapshot has exactly its people at (x, 0, y).

    ``t_tolerance``: how the harness prints the capture time (Godot's JSON keeps 6 decimals).
    """
    srv.daemon.hub.add_publisher(tap)
    first = srv.daemon.hub.latest().seq + 1
    client.wait_for(
        lambda lines: len([s for s in states(lines[after:]) if s["seq"] > first]) >= 20,
        what="20 snapshots applied by the client",
    )
    # /v1/positions serves the very snapshots the tap recorded (same seq -> same body)
    # (the hub sets its latest snapshot before it offers it to publishers, so a GET can see a
    # seq a moment before the tap does: wait for the tap rather than race it)
    for _ in range(5):
        body = WIRE.validate_python(srv.get("/v1/positions").json())
        deadline = time.monotonic() + 5.0
        while body["seq"] not in tap.by_seq and time.monotonic() < deadline:
            time.sleep(0.01)
        assert body == tap.by_seq[body["seq"]].as_dict()
    checked = 0
    for state in states(client.snapshot()[after:]):
        snapshot = tap.by_seq.get(state["seq"])
        if snapshot is None or state["seq"] < first:
            continue
        objects = state["people"]
        assert state["t"] == pytest.approx(snapshot.t, abs=t_tolerance)
        for person in snapshot.people:
            x, y, z = objects[str(person["id"])]
            assert (x, y, z) == pytest.approx((person["x"], 0.0, person["y"]), abs=1e-4)
        # one object per id; ids gone from the snapshot linger only until they despawn
        assert state["objects"] == len(objects) >= len(snapshot.people)
        checked += 1
    assert checked >= 20
    srv.daemon.hub.remove_publisher(tap)
    return checked
