"""The Unity C# client (examples/unity) run under Mono against the live demo daemon on loopback.

``tests/unity/Harness.cs`` drives the client's own code (OnEnable starts its socket task, Update
applies snapshots and moves one GameObject per id) and prints what the scene holds. A tap on the
hub records every snapshot the daemon published, and ``/v1/positions`` is checked against the
same record, so "the client shows what /v1/positions says" is checked seq by seq.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest

from service.hub import Snapshot
from tests.e2e.mqtt_broker import free_port
from tests.e2e.server import RunningServer, running_server
from tests.e2e.toolchains import LineProcess

pytestmark = pytest.mark.timeout(600)
TOKEN = "unity-token"


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


def harness(exe: Path, srv: RunningServer, token: str) -> LineProcess:
    return LineProcess(["mono", str(exe), f"{srv.ws}/v1/stream", token, "0"])


def check_states_match(srv: RunningServer, client: LineProcess, tap: Tap, after: int) -> int:
    """Every client state for a recorded snapshot has exactly its people at (x, 0, y)."""
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
        body = srv.get("/v1/positions").json()
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
        assert state["t"] == pytest.approx(snapshot.t, abs=1e-6)
        for person in snapshot.people:
            x, y, z = objects[str(person["id"])]
            assert (x, y, z) == pytest.approx((person["x"], 0.0, person["y"]), abs=1e-4)
        # one GameObject per id; ids gone from the snapshot linger only until they despawn
        assert state["objects"] == len(objects) >= len(snapshot.people)
        checked += 1
    assert checked >= 20
    srv.daemon.hub.remove_publisher(tap)
    return checked


def test_unity_client_follows_the_stream_and_reconnects_after_a_restart(unity_harness):
    port = free_port()
    connected = "LOG MoMLocalizerClient: connected"
    client: LineProcess | None = None
    try:
        with running_server(token=TOKEN, port=port) as srv:
            srv.wait_for_seq(5)
            client = harness(unity_harness, srv, TOKEN)
            client.wait_for(lambda lines: any(x.startswith(connected) for x in lines))
            check_states_match(srv, client, Tap(), 0)
            assert any(len(s["people"]) >= 2 for s in states(client.snapshot()))
            mark = len(client.snapshot())
        # the daemon is gone: the client notices and keeps retrying with back-off
        client.wait_for(
            lambda lines: any(not s["connected"] for s in statuses(lines[mark:])),
            what="the client to notice the daemon stopped",
        )
        gone = len(client.snapshot())
        client.wait_for(
            lambda lines: any(s["attempts"] >= 3 for s in statuses(lines[gone:])),
            what="reconnect attempts while the daemon is down",
        )
        # counted before the restart: the client's next retry may connect while the new daemon
        # is still starting its pipeline (it did whenever the retry fell in that window)
        back = len(client.snapshot())
        with running_server(token=TOKEN, port=port) as again:
            again.wait_for_seq(5)
            client.wait_for(
                lambda lines: any(x.startswith(connected) for x in lines[back:]),
                what="the client to reconnect to the restarted daemon",
            )
            check_states_match(again, client, Tap(), back)
        log = client.snapshot()
        assert sum(line.startswith(connected) for line in log) == 2
        assert any(line.startswith("WARN MoMLocalizerClient:") for line in log[mark:back])
        assert not any(line.startswith("ERROR") for line in log)
    finally:
        if client is not None:
            client.close()


def test_unity_client_reports_a_wrong_token_and_stops_retrying(unity_harness):
    with running_server(token=TOKEN) as srv:
        srv.wait_for_seq(5)
        client = harness(unity_harness, srv, "not-the-token")
        try:
            client.wait_for(
                lambda lines: any(
                    x.startswith("ERROR") and "rejected the token" in x for x in lines
                ),
                what="the token error",
            )
            rejected = client.wait_for(
                lambda lines: [s for s in statuses(lines) if s["rejected"]],
                what="TokenRejected",
            )
            mark = len(client.snapshot())
            # retrying could not help: over several back-off periods (max 2 s) no new attempt
            client.wait_for(lambda lines: len(statuses(lines[mark:])) >= 8, what="4 s of status")
            later = statuses(client.snapshot())[-1]
            assert rejected[0]["attempts"] == later["attempts"] == 1
            assert later["error"] == "the daemon rejected the token" and not later["connected"]
            assert all(not s["people"] for s in states(client.snapshot()))
        finally:
            client.close()
