"""The Unity C# client (examples/unity) run under Mono against the live demo daemon on loopback.

``tests/unity/Harness.cs`` drives the client's own code (OnEnable starts its socket task, Update
applies snapshots and moves one GameObject per id) and prints what the scene holds; the checks
shared with the Godot client are in ``tests/e2e/client_checks.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.e2e.client_checks import Tap, check_states_match, states, statuses
from tests.e2e.mqtt_broker import free_port
from tests.e2e.server import RunningServer, running_server
from tests.e2e.toolchains import LineProcess

pytestmark = pytest.mark.timeout(600)
TOKEN = "unity-token"


def harness(exe: Path, srv: RunningServer, token: str) -> LineProcess:
    return LineProcess(["mono", str(exe), f"{srv.ws}/v1/stream", token, "0"])


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
        back = len(client.snapshot())  # before the restart: the client may reconnect at once
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
