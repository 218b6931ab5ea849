"""The Godot client (examples/godot) run headless against the live demo daemon on loopback.

Debian's ``godot3-server`` (Godot 3.2.3 without renderer or window, installed by the test setup)
runs ``tests/godot/harness.gd``: the client script on a Spatial in a real SceneTree, its own
WebSocketClient polled once per frame, one node per person id; the harness prints what the scene
holds. The checks shared with the Unity client are in ``tests/e2e/client_checks.py``.
"""

from __future__ import annotations

import pytest

from tests.e2e.client_checks import Tap, check_states_match, states, statuses
from tests.e2e.mqtt_broker import free_port
from tests.e2e.server import RunningServer, running_server
from tests.e2e.toolchains import LineProcess

pytestmark = pytest.mark.timeout(600)
TOKEN = "godot-token"
CONNECTED = "MoMLocalizerClient: connected to "
WARNING = "WARNING: "  # how Godot prints push_warning ("WARNING: call: <text>" in 3.2.3)
# Godot's JSON prints 6 decimals: the capture time (unix seconds) is rounded to the microsecond
T_TOLERANCE = 1e-6


def harness(command: list[str], srv: RunningServer, token: str) -> LineProcess:
    # smoothing 0: nodes jump to each snapshot, so positions compare exactly
    return LineProcess([*command, f"{srv.ws}/v1/stream", token, "0"], quit_line=None)


def test_godot_client_follows_the_stream_and_reconnects_after_a_restart(godot_harness):
    port = free_port()
    client: LineProcess | None = None
    try:
        with running_server(token=TOKEN, port=port) as srv:
            srv.wait_for_seq(5)
            client = harness(godot_harness, srv, TOKEN)
            client.wait_for(lambda lines: "EVENT connected" in lines, what="the connection")
            check_states_match(srv, client, Tap(), 0, T_TOLERANCE)
            assert any(len(s["people"]) >= 2 for s in states(client.snapshot()))
            mark = len(client.snapshot())
        # the daemon is gone: the client notices and keeps retrying with back-off
        client.wait_for(
            lambda lines: any(x.startswith("EVENT disconnected") for x in lines[mark:]),
            what="the client to notice the daemon stopped",
        )
        gone = len(client.snapshot())
        client.wait_for(
            lambda lines: any(s["attempts"] >= 3 for s in statuses(lines[gone:])),
            what="reconnect attempts while the daemon is down",
        )
        down = statuses(client.snapshot()[gone:])[-1]
        assert not down["connected"] and down["error"].startswith("cannot connect to")
        back = len(client.snapshot())  # before the restart: the client may reconnect at once
        with running_server(token=TOKEN, port=port) as again:
            again.wait_for_seq(5)
            client.wait_for(
                lambda lines: "EVENT connected" in lines[back:],
                what="the client to reconnect to the restarted daemon",
            )
            check_states_match(again, client, Tap(), back, T_TOLERANCE)
            up = client.wait_for(
                lambda lines: [s for s in statuses(lines[back:]) if s["connected"]],
                what="a connected status",
            )[-1]
            assert up["error"] == "" and not up["rejected"]
        log = client.snapshot()
        assert sum(line == "EVENT connected" for line in log) == 2
        assert sum(line.startswith(CONNECTED) for line in log) == 2
        retries = [x for x in log[mark:back] if x.startswith(WARNING) and "MoMLocalizerClient" in x]
        assert "connection closed by the daemon" in retries[0]
        # back-off: 0.5 s doubling up to max_backoff_seconds (2 s in the harness)
        delays = [float(x.rsplit("retrying in ", 1)[1].split()[0]) for x in retries]
        assert delays == [min(0.5 * 2**k, 2.0) for k in range(len(delays))]
        assert len(delays) >= 3
        assert not any(line.startswith(("ERROR", "SCRIPT ERROR")) for line in log)
    finally:
        if client is not None:
            client.close()


def test_godot_client_reports_a_wrong_token_and_stops_retrying(godot_harness):
    with running_server(token=TOKEN) as srv:
        srv.wait_for_seq(5)
        client = harness(godot_harness, srv, "not-the-token")
        try:
            client.wait_for(
                lambda lines: any(
                    x.startswith("ERROR") and "rejected the token" in x for x in lines
                ),
                what="the token error",
            )
            client.wait_for(lambda lines: "EVENT token_rejected" in lines, what="the signal")
            rejected = client.wait_for(
                lambda lines: [s for s in statuses(lines) if s["rejected"]],
                what="the rejected status",
            )
            mark = len(client.snapshot())
            # retrying could not help: over several back-off periods (max 2 s) no new attempt
            client.wait_for(lambda lines: len(statuses(lines[mark:])) >= 8, what="4 s of status")
            later = statuses(client.snapshot())[-1]
            assert rejected[0]["attempts"] == later["attempts"] == 1
            assert later["error"] == "the daemon rejected the token" and not later["connected"]
            assert not states(client.snapshot())  # no snapshot was ever applied
        finally:
            client.close()
