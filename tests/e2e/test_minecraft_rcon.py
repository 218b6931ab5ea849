"""The Minecraft bridge (``momloc bridge minecraft``) against a real RCON server implementation.

No Minecraft server installs from the registries the project reaches (the server jar is only on
Mojang's site), so the bridge is driven against rconx (PyPI, LGPL-3.0, a test dependency only):
an independent implementation of the server side of the Source RCON protocol following SRCDS's
conventions (an empty response packet before the auth answer, id -1 for a wrong password, then
the connection is closed). The command handler answers like a Minecraft server would; what is
checked is what arrived at the server: the commands the bridge sent, in order, with the
positions the live daemon published, and the authentication the server saw.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import pytest

from service.outputs.minecraft import WorldMapping
from tests.e2e.client_checks import Tap
from tests.e2e.mqtt_broker import free_port
from tests.e2e.server import RunningServer, running_server

rconx = pytest.importorskip("rconx", reason="rconx (dev dependency) is not installed")

pytestmark = pytest.mark.timeout(300)
PASSWORD = "rcon-secret"
TOKEN = "bridge-token"
ORIGIN = (100.0, 64.0, -20.0)
SUMMON = re.compile(
    r'summon minecraft:armor_stand (\S+) (\S+) (\S+) .*Tags:\["momloc","momloc_(\d+)"\]'
)
MOVE = re.compile(r"tp @e\[tag=momloc_(\d+),limit=1\] (\S+) (\S+) (\S+)(?: (\S+) 0)?$")


@dataclass
class RconLog:
    """What the RCON server received, in order (the handlers run on rconx's worker threads)."""

    logins: list[tuple[str, bool]] = field(default_factory=list)
    commands: list[str] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def authenticate(self, content, info) -> bool:
        accepted = content.text == PASSWORD
        with self.lock:
            self.logins.append((content.text, accepted))
        return accepted

    def execute(self, content, info) -> str:
        text = content.text
        with self.lock:
            self.commands.append(text)
        if text.startswith("summon"):
            return "Summoned new Armor Stand"
        if text.startswith("tp"):
            return "Teleported Armor Stand"
        return "No entity was found"


@contextmanager
def rcon_server() -> Iterator[tuple[int, RconLog]]:
    log = RconLog()
    port = free_port()
    server = rconx.RconServer(
        "127.0.0.1", port, authentication=log.authenticate, command_handler=log.execute
    )
    started = threading.Event()
    thread = threading.Thread(target=server.serve, kwargs={"on_started": started.set})
    thread.start()
    try:
        assert started.wait(30), "the RCON server did not start"
        yield port, log
    finally:
        server.shutdown()
        thread.join(timeout=30)


def bridge(srv: RunningServer, rcon_port: int, password: str, token: str, *extra: str):
    """``momloc bridge minecraft`` as a user runs it (password from the environment)."""
    command = [sys.executable, "-m", "service.cli", "bridge", "minecraft"]
    command += ["--stream", f"{srv.ws}/v1/stream", "--token", token]
    command += ["--rcon-port", str(rcon_port), "--origin", *map(str, ORIGIN), *extra]
    env = {**os.environ, "MOMLOC_RCON_PASSWORD": password}
    return subprocess.run(command, capture_output=True, text=True, timeout=120, env=env)


def published_at(
    tap: Tap, pid: int, x: float, y: float, z: float, yaw: float | None = None
) -> bool:
    """Some published snapshot had person ``pid`` where block (x, y, z) puts them (and walking
    the way ``yaw`` faces, when the command turned the entity)."""
    fx, fy = x - ORIGIN[0], z - ORIGIN[2]
    return y == ORIGIN[1] and any(
        abs(p["x"] - fx) <= 6e-4
        and abs(p["y"] - fy) <= 6e-4
        and (yaw is None or WorldMapping.yaw(p["vx"], p["vy"]) == yaw)
        for s in tap.by_seq.values()
        for p in s.people
        if p["id"] == pid
    )


def test_bridge_sends_the_daemons_positions_to_a_real_rcon_server():
    with running_server(token=TOKEN) as srv, rcon_server() as (rcon_port, log):
        srv.wait_for_seq(5)
        tap = Tap()
        srv.daemon.hub.add_publisher(tap)
        done = bridge(srv, rcon_port, PASSWORD, TOKEN, "--max-snapshots", "20", "--rate", "10")
        srv.daemon.hub.remove_publisher(tap)
    assert done.returncode == 0, done.stderr
    assert "applied 20 snapshots" in done.stdout
    assert log.logins == [(PASSWORD, True)]
    commands = log.commands
    # a crashed earlier run leaves nothing: every momloc entity is removed first and at exit
    assert commands[0] == commands[-1] == "kill @e[tag=momloc]"
    summoned: set[int] = set()
    moves = 0
    for text in commands[1:-1]:
        if summon := SUMMON.match(text):
            x, y, z, pid = *map(float, summon.groups()[:3]), int(summon.group(4))
            assert pid not in summoned and published_at(tap, pid, x, y, z), text
            summoned.add(pid)
        elif move := MOVE.match(text):
            pid, (x, y, z) = int(move.group(1)), map(float, move.groups()[1:4])
            yaw = None if move.group(5) is None else float(move.group(5))
            assert pid in summoned and published_at(tap, pid, x, y, z, yaw), text
            moves += 1
        else:
            killed = re.fullmatch(r"kill @e\[tag=momloc_(\d+)\]", text)
            assert killed is not None, text
            pid = int(killed.group(1))
            assert pid in summoned, text  # an id that left the stream
            summoned.remove(pid)
    assert len(summoned) >= 2 and moves >= 20


def test_bridge_reports_a_wrong_rcon_password_and_a_wrong_token():
    with running_server(token=TOKEN) as srv, rcon_server() as (rcon_port, log):
        srv.wait_for_seq(5)
        wrong_password = bridge(srv, rcon_port, "not-the-password", TOKEN)
        wrong_token = bridge(srv, rcon_port, PASSWORD, "not-the-token")
    assert wrong_password.returncode == 2
    assert "password rejected" in wrong_password.stderr
    assert wrong_token.returncode == 2
    assert "token rejected" in wrong_token.stderr
    for run in (wrong_password, wrong_token):
        assert "Traceback" not in run.stderr
    # the server saw the wrong password refused, then the right one (the stream refused the token)
    assert log.logins == [("not-the-password", False), (PASSWORD, True)]
    assert log.commands[0] == log.commands[-1] == "kill @e[tag=momloc]"
    assert not any(c.startswith(("summon", "tp")) for c in log.commands)
