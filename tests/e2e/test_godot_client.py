"""The Godot client (examples/godot) run headless against the live demo daemon on loopback.

Debian's ``godot3-server`` (Godot 3.2.3 without renderer or window, installed by the test setup)
runs ``tests/godot/harness.gd``: the client script on a Spatial in a real SceneTree, its own
WebSocketClient polled once per frame, one node per person id; the harness prints what the scene
holds. The checks shared with the Unity client are in ``tests/e2e/client_checks.py``; smoothing,
despawning and malformed messages are checked against a scripted stream whose positions the test
chose.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import threading

import pytest
from websockets.asyncio.server import Server, ServerConnection, serve

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


class ScriptedStream:
    """A WebSocket server (in a thread) sending ``messages`` every ``period`` seconds to each
    client, then keeping the connection open; records each handshake's Authorization header.

    The live daemon's people wander at random; smoothing and despawning need a scene whose
    positions the test chose."""

    def __init__(self, messages: list[str], period: float = 0.1) -> None:
        self.messages, self.period = messages, period
        self.authorization: list[str | None] = []
        self.port = free_port()
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)

    async def _handler(self, ws: ServerConnection) -> None:
        assert ws.request is not None
        self.authorization.append(ws.request.headers.get("Authorization"))
        for message in self.messages:
            await ws.send(message)
            await asyncio.sleep(self.period)
        await ws.wait_closed()

    def __enter__(self) -> ScriptedStream:
        async def start() -> Server:
            return await serve(self._handler, "127.0.0.1", self.port)

        self._thread.start()
        self._server = asyncio.run_coroutine_threadsafe(start(), self._loop).result(30)
        return self

    def __exit__(self, *exc: object) -> None:
        async def stop() -> None:
            self._server.close()
            await self._server.wait_closed()

        asyncio.run_coroutine_threadsafe(stop(), self._loop).result(30)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=30)
        self._loop.close()


def scripted_snapshot(seq: int, people: dict[int, tuple[float, float]]) -> str:
    persons = [
        {"id": pid, "x": x, "y": y, "vx": 0.0, "vy": 0.0, "confidence": 0.9, "cameras": [0]}
        for pid, (x, y) in people.items()
    ]
    return json.dumps({"v": 1, "seq": seq, "t": 1000.0 + seq / 10, "people": persons})


def test_godot_client_smooths_motion_despawns_and_skips_bad_messages(godot_harness):
    still = (1.0, 1.0)  # person 8 never moves
    messages = ["{not json", "[1, 2]"]
    messages += [scripted_snapshot(s, {7: (0.0, 0.0), 8: still}) for s in range(1, 4)]
    messages += [scripted_snapshot(s, {7: (4.0, 0.0), 8: still}) for s in range(4, 31)]
    messages += [scripted_snapshot(s, {8: still}) for s in range(31, 61)]  # 7 left at seq 31
    with ScriptedStream(messages) as stream:
        url = f"ws://127.0.0.1:{stream.port}/v1/stream"
        # smoothing 5/s: a 4 m jump is 63 % done after 0.2 s, 99.9 % after 1.4 s
        client = LineProcess([*godot_harness, url, "tok", "5"], quit_line=None)
        try:
            client.wait_for(lambda lines: any(s["seq"] == 60 for s in states(lines)), what="seq 60")
            lines = client.snapshot()
        finally:
            client.close()
    assert stream.authorization == ["Bearer tok"]  # the token travels as a header, not in the URL
    bad = [x for x in lines if x.startswith(WARNING) and "bad message skipped" in x]
    assert len(bad) == 2  # both skipped, the connection kept
    assert not any(x.startswith("EVENT disconnected") for x in lines)
    by_seq = {s["seq"]: s for s in states(lines)}
    assert by_seq[3]["people"]["7"] == pytest.approx([0.0, 0.0, 0.0])  # a new id appears in place
    approach = [s["people"]["7"] for seq, s in sorted(by_seq.items()) if 4 <= seq <= 30]
    xs = [x for x, _, _ in approach]
    assert 0.0 < xs[0] < 2.0  # the jump to x = 4 is smoothed, not taken in one frame
    assert all(a <= b <= 4.0 for a, b in itertools.pairwise(xs))
    assert xs[-1] == pytest.approx(4.0, abs=0.01)
    assert all(y == 0.0 and z == pytest.approx(0.0, abs=1e-6) for _, y, z in approach)
    assert all(s["people"]["8"] == pytest.approx([1.0, 0.0, 1.0]) for s in by_seq.values())
    # person 7 left at seq 31: the node lingers (despawn_seconds = 2) and then is freed
    after = [s for seq, s in sorted(by_seq.items()) if seq >= 31]
    assert any("7" in s["people"] for s in after)
    assert "7" not in after[-1]["people"] and after[-1]["objects"] == 1
