"""Minecraft bridge: one entity per tracked person, moved through the server's RCON port.

RCON (the Source RCON protocol, which Minecraft Java servers speak when ``enable-rcon=true``)
-------------------------------------------------------------------------------------------
Every packet is ``int32 length | int32 request id | int32 type | body (ASCII) | 0x00 | 0x00``, all
integers little-endian, ``length`` counting everything after itself (so 10 + len(body)). The
client logs in with type 3 (``SERVERDATA_AUTH``) and the password as body; the server answers type
2 with the same id, or id -1 when the password is wrong (Source servers send an empty type 0 packet
first; we skip it). Commands are type 2 (``SERVERDATA_EXECCOMMAND``), answered by type 0 packets
carrying the command's output with the command's id. Replies to an older id (fragments of a long
output) are skipped, so a long answer can never shift later answers by one.

Bridge
------
The bridge subscribes to ``WS /v1/stream``. A reader task keeps only the newest snapshot; the
writer applies it at most ``rate_hz`` times per second, because a Minecraft server executes RCON
commands on its tick thread and a 30 Hz stream of ``tp`` commands per person would lag it. For each
person id: the first sighting ``summon``s an entity tagged ``momloc`` and ``momloc_<id>`` (an
armor stand by default, named after the id, no gravity); later snapshots ``tp`` it when it moved
more than ``min_move`` blocks, facing its walking direction; an id leaving the stream is
``kill``ed. At start and at exit every ``momloc``-tagged entity is removed, so a crashed earlier
run leaves nothing behind.

Floor → world mapping: Minecraft X = origin X + scale · x, Z = origin Z + scale · y, Y = origin Y
(floor height, blocks). One block is one metre, so ``scale = 1`` keeps real distances.

Both connections reconnect with back-off; a rejected token (close code 4401) or a wrong RCON
password is a user error and stops the bridge with one line.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import logging
import math
import struct
from dataclasses import dataclass, field
from string import Template
from typing import Any

from common.errors import MomlocError

log = logging.getLogger(__name__)

AUTH, EXEC, RESPONSE = 3, 2, 0
MAX_PACKET = 4096 + 14  # a server never sends more per packet
AUTH_CLOSE_CODE = 4401
DEFAULT_NBT = (
    '{Tags:["$tag","${tag}_$id"],CustomName:\'"$name"\',CustomNameVisible:1b,'
    "NoGravity:1b,Invulnerable:1b}"
)


def encode_packet(request_id: int, kind: int, body: str) -> bytes:
    """One RCON packet (see the module docstring)."""
    payload = body.encode("utf-8") + b"\x00\x00"
    return struct.pack("<iii", len(payload) + 8, request_id, kind) + payload


async def read_packet(reader: asyncio.StreamReader) -> tuple[int, int, str]:
    """``(request id, type, body)`` of the next packet; raises on a malformed length."""
    (length,) = struct.unpack("<i", await reader.readexactly(4))
    if not 10 <= length <= MAX_PACKET:
        raise ConnectionError(f"RCON: malformed packet length {length}")
    data = await reader.readexactly(length)
    request_id, kind = struct.unpack("<ii", data[:8])
    return request_id, kind, data[8:-2].decode("utf-8", errors="replace")


class RconClient:
    """Minimal asyncio RCON client: ``await connect()``, ``await command(text)``, ``close()``."""

    def __init__(self, host: str, port: int, password: str, timeout: float = 5.0) -> None:
        self.host, self.port, self.password, self.timeout = host, port, password, timeout
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._ids = itertools.count(1)

    async def connect(self) -> None:
        """Open the TCP connection and log in (wrong password: :class:`MomlocError`)."""
        try:
            self._reader, self._writer = await asyncio.wait_for(
                asyncio.open_connection(self.host, self.port), self.timeout
            )
        except (OSError, TimeoutError) as error:
            raise ConnectionError(
                f"RCON {self.host}:{self.port}: cannot connect ({error})"
            ) from None
        request_id = next(self._ids)
        await self._send(request_id, AUTH, self.password)
        while True:
            answer_id, kind, _ = await self._read()
            if kind != EXEC:  # Source servers send an empty RESPONSE first
                continue
            if answer_id == -1:
                self.close()
                raise MomlocError(f"RCON {self.host}:{self.port}: password rejected")
            if answer_id == request_id:
                return

    async def command(self, text: str) -> str:
        """Run one console command (no leading slash needed) and return its output."""
        if self._writer is None:
            raise ConnectionError("RCON: not connected")
        request_id = next(self._ids)
        await self._send(request_id, EXEC, text)
        while True:
            answer_id, _, body = await self._read()
            if answer_id == request_id:
                return body

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
        self._reader = self._writer = None

    async def _send(self, request_id: int, kind: int, body: str) -> None:
        assert self._writer is not None
        self._writer.write(encode_packet(request_id, kind, body))
        await self._writer.drain()

    async def _read(self) -> tuple[int, int, str]:
        assert self._reader is not None
        try:
            return await asyncio.wait_for(read_packet(self._reader), self.timeout)
        except (asyncio.IncompleteReadError, TimeoutError) as error:
            raise ConnectionError(f"RCON: connection lost ({error!r})") from None


@dataclass(frozen=True)
class WorldMapping:
    """Floor metres → Minecraft block coordinates (see the module docstring)."""

    origin: tuple[float, float, float] = (0.0, 64.0, 0.0)
    scale: float = 1.0

    def to_minecraft(self, x: float, y: float) -> tuple[float, float, float]:
        ox, oy, oz = self.origin
        return ox + self.scale * x, oy, oz + self.scale * y

    @staticmethod
    def yaw(vx: float, vy: float) -> float | None:
        """Minecraft yaw (0 = +Z/south, 90 = -X/west) of the walking direction; None if still."""
        if math.hypot(vx, vy) < 0.1:
            return None
        return round(math.degrees(math.atan2(-vx, vy)), 1)


@dataclass
class BridgeConfig:
    stream_url: str
    rcon_host: str = "127.0.0.1"
    rcon_port: int = 25575
    rcon_password: str = ""
    token: str | None = None
    mapping: WorldMapping = field(default_factory=WorldMapping)
    entity: str = "minecraft:armor_stand"
    nbt: str = DEFAULT_NBT
    tag: str = "momloc"
    rate_hz: float = 10.0
    min_move: float = 0.05
    max_snapshots: int | None = None  # stop after this many applied snapshots (scripting, tests)
    backoff_s: tuple[float, float] = (0.5, 10.0)


class MinecraftBridge:
    """Applies stream snapshots to Minecraft entities (see the module docstring)."""

    def __init__(self, config: BridgeConfig) -> None:
        if not config.stream_url.startswith(("ws://", "wss://")):
            raise MomlocError(f"--stream {config.stream_url!r}: expected a ws:// or wss:// URL")
        if config.rate_hz <= 0:
            raise MomlocError("--rate must be positive")
        self.config = config
        self.rcon = RconClient(config.rcon_host, config.rcon_port, config.rcon_password)
        self.entities: dict[int, tuple[float, float, float]] = {}
        self.applied = 0
        self._latest: dict[str, Any] | None = None
        self._fresh = asyncio.Event()

    # -- commands ------------------------------------------------------------------------------
    def summon_command(self, person_id: int, pos: tuple[float, float, float]) -> str:
        nbt = Template(self.config.nbt).safe_substitute(
            tag=self.config.tag, id=person_id, name=f"person {person_id}"
        )
        return f"summon {self.config.entity} {_xyz(pos)} {nbt}"

    def move_command(
        self, person_id: int, pos: tuple[float, float, float], yaw: float | None
    ) -> str:
        facing = "" if yaw is None else f" {yaw} 0"
        return f"tp @e[tag={self.config.tag}_{person_id},limit=1] {_xyz(pos)}{facing}"

    def remove_command(self, person_id: int | None = None) -> str:
        tag = self.config.tag if person_id is None else f"{self.config.tag}_{person_id}"
        return f"kill @e[tag={tag}]"

    def commands_for(self, snapshot: dict[str, Any]) -> list[str]:
        """The commands that bring the world in line with ``snapshot`` (updates ``entities``)."""
        out = []
        seen = set()
        for person in snapshot.get("people", []):
            pid = int(person["id"])
            seen.add(pid)
            pos = self.config.mapping.to_minecraft(float(person["x"]), float(person["y"]))
            yaw = WorldMapping.yaw(float(person.get("vx", 0.0)), float(person.get("vy", 0.0)))
            if pid not in self.entities:
                out.append(self.summon_command(pid, pos))
                if yaw is not None:
                    out.append(self.move_command(pid, pos, yaw))
            elif math.dist(pos, self.entities[pid]) < self.config.min_move:
                continue
            else:
                out.append(self.move_command(pid, pos, yaw))
            self.entities[pid] = pos
        for pid in sorted(set(self.entities) - seen):
            out.append(self.remove_command(pid))
            del self.entities[pid]
        return out

    # -- loops ---------------------------------------------------------------------------------
    async def run(self) -> int:
        """Bridge until cancelled or ``max_snapshots`` applied; returns the applied count."""
        await self._connect_rcon()
        try:
            reader = asyncio.create_task(self._read_stream())
            try:
                await self._apply_loop(reader)
            finally:
                reader.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await reader
        finally:
            with contextlib.suppress(ConnectionError, MomlocError):
                await self.rcon.command(self.remove_command())
            self.rcon.close()
        return self.applied

    async def _apply_loop(self, reader: asyncio.Task) -> None:
        period = 1.0 / self.config.rate_hz
        loop = asyncio.get_running_loop()
        while self.config.max_snapshots is None or self.applied < self.config.max_snapshots:
            waiter = asyncio.create_task(self._fresh.wait())
            await asyncio.wait({waiter, reader}, return_when=asyncio.FIRST_COMPLETED)
            if reader.done():  # the stream reader only ends with an error
                waiter.cancel()
                reader.result()
            self._fresh.clear()
            snapshot, self._latest = self._latest, None
            if snapshot is None:
                continue
            started = loop.time()
            for command in self.commands_for(snapshot):
                await self._command(command)
            self.applied += 1
            await asyncio.sleep(max(0.0, period - (loop.time() - started)))

    async def _command(self, command: str) -> None:
        try:
            await self.rcon.command(command)
        except ConnectionError:
            await self._connect_rcon()  # a restarted server lost the entities: rebuild them
            self.entities.clear()

    async def _connect_rcon(self) -> None:
        delay = self.config.backoff_s[0]
        while True:
            try:
                await self.rcon.connect()
                await self.rcon.command(self.remove_command())
                return
            except ConnectionError as error:
                log.warning("%s; retrying in %.1f s", error, delay)
                await asyncio.sleep(delay)
                delay = min(delay * 2, self.config.backoff_s[1])

    async def _read_stream(self) -> None:
        from websockets.asyncio.client import connect
        from websockets.exceptions import ConnectionClosed, InvalidStatus

        headers = {"Authorization": f"Bearer {self.config.token}"} if self.config.token else None
        delay = self.config.backoff_s[0]
        while True:
            try:
                async with connect(self.config.stream_url, additional_headers=headers) as ws:
                    delay = self.config.backoff_s[0]
                    async for message in ws:
                        try:
                            snapshot = json.loads(message)
                        except ValueError:
                            log.warning("stream: skipping a message that is not JSON")
                            continue
                        self._latest = snapshot
                        self._fresh.set()
            except ConnectionClosed as closed:
                if closed.rcvd is not None and closed.rcvd.code == AUTH_CLOSE_CODE:
                    raise MomlocError(f"{self.config.stream_url}: token rejected") from None
            except InvalidStatus as error:
                if error.response.status_code in (401, 403):
                    raise MomlocError(f"{self.config.stream_url}: token rejected") from None
            except (OSError, TimeoutError) as error:
                log.warning(
                    "stream %s: %s; retrying in %.1f s", self.config.stream_url, error, delay
                )
            await asyncio.sleep(delay)
            delay = min(delay * 2, self.config.backoff_s[1])


def _xyz(pos: tuple[float, float, float]) -> str:
    return " ".join(f"{v:.3f}" for v in pos)
