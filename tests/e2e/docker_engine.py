"""The Docker engine as the image tests drive it: the ``docker`` CLI, an engine check that skips
with the reason, and a container's life from the host (run, health, HEALTHCHECK, stop).

Containers use the host's network, as the engine may run without a bridge (``--bridge=none``,
tools/with_dockerd.sh) on CI.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import socket
import subprocess
import time
from pathlib import Path

import httpx
import pytest

GRACE_S = 10
BINFMT = Path("/proc/sys/fs/binfmt_misc")


def docker(*args: str, check: bool = True, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["docker", *args], capture_output=True, text=True, timeout=timeout, check=check
    )


def require_engine() -> None:
    """Skip unless the image tests were asked for (they build for minutes) and an engine runs."""
    if os.environ.get("MOMLOC_DOCKER_TESTS") != "1":
        pytest.skip("Docker image tests are opt-in: make test-docker (builds for minutes)")
    if shutil.which("docker") is None:
        pytest.skip("no docker client on this machine")
    info = docker("info", check=False, timeout=30)
    if info.returncode != 0:
        reason = (info.stderr.strip().splitlines() or ["no answer"])[-1]
        pytest.skip(f"no Docker engine running: {reason}")


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def run_detached(image: str, port: int, *extra: str) -> str:
    started = docker("run", "-d", "--network", "host", "-e", f"MOMLOC_PORT={port}", *extra, image)
    return started.stdout.strip()


def health(port: int, timeout: float = 120) -> dict:
    deadline = time.time() + timeout
    while True:
        try:
            return httpx.get(f"http://127.0.0.1:{port}/v1/health", timeout=5).json()
        except httpx.HTTPError:
            if time.time() > deadline:
                raise
            time.sleep(0.5)


def wait_healthy(container: str, timeout: float = 180) -> None:
    deadline = time.time() + timeout
    while (status := inspect(container)["State"]["Health"]["Status"]) != "healthy":
        assert status != "unhealthy" and time.time() < deadline, status
        time.sleep(1)


def inspect(container: str) -> dict:
    return json.loads(docker("inspect", container).stdout)[0]


def stop_cleanly(container: str) -> None:
    started = time.monotonic()
    docker("stop", "-t", str(GRACE_S), container)
    assert time.monotonic() - started < GRACE_S, "not stopped by SIGTERM within the grace period"
    assert inspect(container)["State"]["ExitCode"] == 0  # not 137: no SIGKILL was needed


def arm64_emulation_missing(binfmt: Path = BINFMT) -> str | None:
    """What stops this machine running linux/arm64 containers, or None when nothing does.

    An x86 kernel runs arm64 binaries through a binfmt_misc handler that hands them to QEMU; the
    handler needs the F flag (interpreter opened when registered), or a container, which has no
    QEMU inside, cannot reach it. Docker asks nothing else of the machine."""
    if platform.machine() == "aarch64":
        return None
    if not (binfmt / "register").exists():
        return f"binfmt_misc is not mounted at {binfmt} (mounting it needs root)"
    handler = binfmt / "qemu-aarch64"
    if not handler.exists():
        return "no qemu-aarch64 handler in binfmt_misc (Debian's qemu-user-static registers it)"
    lines = handler.read_text().splitlines()
    if "enabled" not in lines:
        return "the qemu-aarch64 binfmt handler is disabled (update-binfmts --enable qemu-aarch64)"
    flags = next((line.split(":", 1)[1] for line in lines if line.startswith("flags:")), "")
    if "F" not in flags:
        return "the qemu-aarch64 binfmt handler lacks the F flag, so containers cannot reach QEMU"
    return None
