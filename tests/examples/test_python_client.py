"""Run examples/python_client.py as a user would, against a small WebSocket server on loopback."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import time
from pathlib import Path

from websockets.asyncio.server import ServerConnection, serve

CLIENT = Path(__file__).resolve().parents[2] / "examples" / "python_client.py"


def snapshot(seq: int) -> str:
    people = [
        {"id": 7, "x": 1.5, "y": -0.25, "vx": 0.5, "vy": 0.0, "confidence": 0.8, "cameras": [0, 1]}
    ]
    return json.dumps({"v": 1, "seq": seq, "t": time.time(), "people": people})


async def run_client(*args: str) -> subprocess.CompletedProcess:
    return await asyncio.to_thread(
        subprocess.run,
        [sys.executable, str(CLIENT), "--max-backoff", "0.2", *args],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_prints_positions_and_reconnects() -> None:
    async def scenario() -> subprocess.CompletedProcess:
        connections = 0

        async def handler(ws: ServerConnection) -> None:
            nonlocal connections
            connections += 1
            if connections == 1:  # first connection: one snapshot, then the "daemon restarts"
                await ws.send(snapshot(1))
                return
            assert ws.request is not None
            assert ws.request.headers.get("Authorization") == "Bearer s3cret"
            for seq in (2, 3):
                await ws.send(snapshot(seq))
            await ws.wait_closed()

        async with serve(handler, "127.0.0.1", 0) as server:
            port = server.sockets[0].getsockname()[1]
            url = f"ws://127.0.0.1:{port}/v1/stream"
            return await run_client("--url", url, "--token", "s3cret", "--count", "3")

    result = asyncio.run(scenario())
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert [line.split()[1] for line in lines if line.startswith("seq")] == ["1", "2", "3"]
    assert "#7 (+1.50, -0.25) m  v=(+0.50, +0.00) m/s  conf 0.80  cams [0, 1]" in result.stdout
    assert "reconnecting" in result.stderr


def test_rejected_token_exits_2() -> None:
    async def scenario() -> subprocess.CompletedProcess:
        async def handler(ws: ServerConnection) -> None:
            await ws.close(4401, "missing or wrong token")

        async with serve(handler, "127.0.0.1", 0) as server:
            port = server.sockets[0].getsockname()[1]
            return await run_client("--url", f"ws://127.0.0.1:{port}/v1/stream")

    result = asyncio.run(scenario())
    assert result.returncode == 2
    assert "rejected the token" in result.stderr
