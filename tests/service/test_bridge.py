"""Minecraft bridge against a fake RCON server and a scripted WebSocket stream on loopback."""

from __future__ import annotations

import asyncio
import json
import struct

import pytest
from websockets.asyncio.server import ServerConnection, serve

from common.errors import MomlocError
from service.cli import main
from service.outputs.minecraft import BridgeConfig, MinecraftBridge, WorldMapping, encode_packet


class FakeRcon:
    """Speaks the Source RCON protocol like a Minecraft/Source server (parsed independently)."""

    def __init__(self, password: str, drop_after: int | None = None) -> None:
        self.password = password
        self.commands: list[str] = []
        self.logins = 0
        self.drop_after = drop_after  # close the connection after this many commands, once

    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while True:
                size = struct.unpack("<i", await reader.readexactly(4))[0]
                data = await reader.readexactly(size)
                request_id, kind = struct.unpack("<ii", data[:8])
                assert data[-2:] == b"\x00\x00", "body and packet must be NUL-terminated"
                body = data[8:-2].decode()
                if kind == 3:
                    writer.write(self.packet(request_id, 0, ""))  # Source: empty RESPONSE first
                    ok = body == self.password
                    self.logins += ok
                    writer.write(self.packet(request_id if ok else -1, 2, ""))
                elif kind == 2:
                    self.commands.append(body)
                    # A stale fragment of an earlier answer, then the real one.
                    writer.write(self.packet(request_id - 1, 0, "stale"))
                    writer.write(self.packet(request_id, 0, f"ran {body}"))
                    if self.drop_after is not None and len(self.commands) == self.drop_after:
                        self.drop_after = None
                        writer.close()
                        return
                await writer.drain()
        except (asyncio.IncompleteReadError, ConnectionError):
            writer.close()

    @staticmethod
    def packet(request_id: int, kind: int, body: str) -> bytes:
        raw = body.encode() + b"\x00\x00"
        return struct.pack("<iii", 8 + len(raw), request_id, kind) + raw


async def start_rcon(fake: FakeRcon) -> tuple[asyncio.Server, int]:
    server = await asyncio.start_server(fake.handle, "127.0.0.1", 0)
    return server, server.sockets[0].getsockname()[1]


def person(pid: int, x: float, y: float, vx: float = 0.0, vy: float = 0.0) -> dict:
    return {"id": pid, "x": x, "y": y, "vx": vx, "vy": vy, "confidence": 1.0, "cameras": [0]}


SNAPSHOTS = [
    {"v": 1, "seq": 1, "t": 0.0, "people": [person(1, 1.0, 2.0), person(2, 3.0, 4.0, 1.0, 0.0)]},
    {"v": 1, "seq": 2, "t": 0.1, "people": [person(1, 1.5, 2.0, 0.0, 1.0), person(2, 3.01, 4.0)]},
    {"v": 1, "seq": 3, "t": 0.2, "people": [person(1, 1.5, 2.0, 0.0, 1.0)]},
]

EXPECTED = [
    "kill @e[tag=momloc]",
    'summon minecraft:armor_stand 102.000 64.000 -16.000 {Tags:["momloc","momloc_1"],'
    "CustomName:'\"person 1\"',CustomNameVisible:1b,NoGravity:1b,Invulnerable:1b}",
    'summon minecraft:armor_stand 106.000 64.000 -12.000 {Tags:["momloc","momloc_2"],'
    "CustomName:'\"person 2\"',CustomNameVisible:1b,NoGravity:1b,Invulnerable:1b}",
    "tp @e[tag=momloc_2,limit=1] 106.000 64.000 -12.000 -90.0 0",  # walking +x = east = -90°
    "tp @e[tag=momloc_1,limit=1] 103.000 64.000 -16.000 -0.0 0",  # walking +y = south = 0°
    "kill @e[tag=momloc_2]",  # person 2 left (its 1 cm step was below min_move)
    "kill @e[tag=momloc]",  # clean-up at exit
]


def config(ws_port: int, rcon_port: int, **changes) -> BridgeConfig:
    base = BridgeConfig(
        stream_url=f"ws://127.0.0.1:{ws_port}/v1/stream",
        rcon_port=rcon_port,
        rcon_password="secret",
        mapping=WorldMapping(origin=(100.0, 64.0, -20.0), scale=2.0),
        rate_hz=1000.0,
        backoff_s=(0.01, 0.05),
    )
    for key, value in changes.items():
        setattr(base, key, value)
    return base


async def scripted_stream(bridge_ref: list, close_after: int | None = None):
    """A stream server sending SNAPSHOTS one at a time, each once the bridge applied the last."""
    sent = 0

    async def handler(ws: ServerConnection) -> None:
        nonlocal sent
        while sent < len(SNAPSHOTS):
            await ws.send(json.dumps(SNAPSHOTS[sent]))
            sent += 1
            for _ in range(500):
                if bridge_ref[0].applied >= sent:
                    break
                await asyncio.sleep(0.01)
            if close_after is not None and sent == close_after:
                return  # drop the client: the bridge must reconnect
        await ws.wait_closed()

    return await serve(handler, "127.0.0.1", 0)


def test_packet_layout_matches_the_protocol() -> None:
    assert encode_packet(1, 2, "list") == (
        b"\x0e\x00\x00\x00\x01\x00\x00\x00\x02\x00\x00\x00list\x00\x00"
    )


@pytest.mark.parametrize("close_after", [None, 1])
def test_bridge_moves_one_entity_per_id(close_after: int | None) -> None:
    async def scenario() -> None:
        fake = FakeRcon("secret")
        rcon_server, rcon_port = await start_rcon(fake)
        bridge_ref: list = [None]
        ws_server = await scripted_stream(bridge_ref, close_after)
        ws_port = ws_server.sockets[0].getsockname()[1]
        bridge = MinecraftBridge(config(ws_port, rcon_port, max_snapshots=3))
        bridge_ref[0] = bridge
        assert await asyncio.wait_for(bridge.run(), 20) == 3
        ws_server.close()
        rcon_server.close()
        assert fake.commands == EXPECTED
        assert fake.logins == 1

    asyncio.run(scenario())


def test_rcon_reconnect_rebuilds_entities() -> None:
    async def scenario() -> None:
        fake = FakeRcon("secret", drop_after=3)  # dies right after summoning person 2
        rcon_server, rcon_port = await start_rcon(fake)
        bridge_ref: list = [None]
        ws_server = await scripted_stream(bridge_ref)
        bridge = MinecraftBridge(
            config(ws_server.sockets[0].getsockname()[1], rcon_port, max_snapshots=3)
        )
        bridge_ref[0] = bridge
        await asyncio.wait_for(bridge.run(), 20)
        ws_server.close()
        rcon_server.close()
        assert fake.logins == 2
        # After the reconnect: leftovers cleared, then people re-summoned from the next snapshot.
        after = fake.commands[3:]
        assert after[0] == "kill @e[tag=momloc]"
        assert sum(c.startswith("summon") for c in after) == 2
        assert after[-1] == "kill @e[tag=momloc]"

    asyncio.run(scenario())


def test_wrong_password_and_rejected_token_are_user_errors() -> None:
    async def scenario() -> None:
        fake = FakeRcon("secret")
        rcon_server, rcon_port = await start_rcon(fake)

        async def reject(ws: ServerConnection) -> None:
            await ws.close(4401, "missing or wrong token")

        ws_server = await serve(reject, "127.0.0.1", 0)
        ws_port = ws_server.sockets[0].getsockname()[1]
        with pytest.raises(MomlocError, match="password rejected"):
            await MinecraftBridge(config(ws_port, rcon_port, rcon_password="nope")).run()
        with pytest.raises(MomlocError, match="token rejected"):
            await asyncio.wait_for(MinecraftBridge(config(ws_port, rcon_port)).run(), 20)
        ws_server.close()
        rcon_server.close()

    asyncio.run(scenario())


def test_cli_bridge_minecraft(capsys: pytest.CaptureFixture[str]) -> None:
    async def scenario() -> int:
        fake = FakeRcon("pw")
        rcon_server, rcon_port = await start_rcon(fake)

        async def one(ws: ServerConnection) -> None:
            await ws.send(json.dumps(SNAPSHOTS[0]))
            await ws.wait_closed()

        ws_server = await serve(one, "127.0.0.1", 0)
        ws_port = ws_server.sockets[0].getsockname()[1]
        argv = ["bridge", "minecraft", "--stream", f"ws://127.0.0.1:{ws_port}/v1/stream"]
        argv += ["--rcon-port", str(rcon_port), "--rcon-password", "pw", "--max-snapshots", "1"]
        argv += ["--origin", "0", "70", "0", "--entity", "minecraft:zombie"]
        code = await asyncio.to_thread(main, argv)
        ws_server.close()
        rcon_server.close()
        assert fake.commands[1].startswith("summon minecraft:zombie 1.000 70.000 2.000 ")
        return code

    assert asyncio.run(scenario()) == 0
    assert "applied 1 snapshots" in capsys.readouterr().out


def test_cli_bridge_needs_password(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("MOMLOC_RCON_PASSWORD", raising=False)
    assert main(["bridge", "minecraft"]) == 2
    assert "--rcon-password" in capsys.readouterr().err
    assert main(["bridge", "minecraft", "--rcon-password", "x", "--stream", "http://h"]) == 2
    assert "ws://" in capsys.readouterr().err
