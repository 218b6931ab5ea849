"""`momloc demo` as a user runs it: a subprocess that prints the URLs and serves the map."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import httpx
import pytest

from tests.e2e.server import interrupt

pytestmark = pytest.mark.timeout(120)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def demo_process(port: int, **env: str) -> subprocess.Popen:
    """``momloc demo --port PORT`` as a user starts it: no MOMLOC_ variables but ``env``."""
    clean = {k: v for k, v in os.environ.items() if not k.startswith("MOMLOC_")}
    return subprocess.Popen(
        [sys.executable, "-m", "service.cli", "demo", "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**clean, **env},
    )


def test_demo_command_prints_urls_and_serves():
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOMLOC_")}
    proc = demo_process(port)
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline() for _ in range(3)]
        assert f"live map:  http://127.0.0.1:{port}/" in lines[1], lines
        assert f"stream:    ws://127.0.0.1:{port}/v1/stream" in lines[2], lines
        deadline = time.time() + 60
        while True:
            # the port is listening from the banner on; the app answers once started
            health = httpx.get(f"http://127.0.0.1:{port}/v1/health", timeout=30).json()
            if health["pipeline"]["frames_processed"] > 5 or time.time() > deadline:
                break
            time.sleep(0.2)
        assert health["model"]["loaded"] and health["pipeline"]["frames_processed"] > 5
        assert "MoM Localizer" in httpx.get(f"http://127.0.0.1:{port}/").text
        # a second daemon on the same port is a one-line error, exit code 2
        again = subprocess.run(
            [sys.executable, "-m", "service.cli", "demo", "--port", str(port)],
            capture_output=True,
            text=True,
            timeout=60,
            env=env,
        )
        assert again.returncode == 2 and "cannot listen on 127.0.0.1" in again.stderr
        assert "Traceback" not in again.stderr
    finally:
        interrupt(proc)
    assert proc.returncode in (0, 130, -signal.SIGINT)


def test_demo_in_privacy_mode_from_the_environment():
    """``MOMLOC_PRIVACY=positions_only momloc demo``: the banner, health and the snapshot say it."""
    port = free_port()
    proc = demo_process(port, MOMLOC_PRIVACY="positions_only")
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline() for _ in range(5)]
        assert "privacy:   positions only, no camera image" in lines[4], lines
        base = f"http://127.0.0.1:{port}"
        assert httpx.get(base + "/v1/health", timeout=30).json()["privacy"] == "positions_only"
        refused = httpx.get(base + "/v1/cameras/0/snapshot.jpg", timeout=30)
        assert refused.status_code == 403 and "MOMLOC_PRIVACY" in refused.json()["detail"]
    finally:
        interrupt(proc)
