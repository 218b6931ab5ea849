"""The Docker image for linux/arm64 (Raspberry Pi 5 and Pi-class boards), built and run on this
x86 machine under QEMU: the same Dockerfile with the arm64 base, the demo healthy, NanoDet run by
the runtime the docs promise an arm64 machine (ncnn).

Opt-in with the other image tests (``make test-docker-arm64``, which also registers QEMU with
binfmt_misc: tools/with_arm64_emulation.sh). Skipped with one line naming the missing capability
where the machine cannot emulate arm64. The base image is built from Debian's arm64 packages
(``docker/make_base_image.sh``), so no registry is needed. Emulation says nothing about a Pi's
speed: timings under QEMU are those of the emulator, so the test waits on states, never on times.
The module's timeout bounds the step in CI (a cold run builds the base and installs the wheels
under QEMU; later runs reuse the engine's images and layers).
"""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest

from tests.e2e.docker_engine import (
    arm64_emulation_missing,
    docker,
    free_port,
    health,
    inspect,
    require_engine,
    run_detached,
    stop_cleanly,
    wait_healthy,
)

pytestmark = [pytest.mark.docker, pytest.mark.timeout(1200)]
ROOT = Path(__file__).resolve().parents[2]
PLATFORM = "linux/arm64"
BASE = "arm64v8/python:3.11-slim"  # Docker Hub's name for the arm64 variant of python:3.11-slim
TAG = "momloc:test-arm64"


@pytest.fixture(scope="module")
def arm64_image() -> str:
    require_engine()
    missing = arm64_emulation_missing()
    if missing is not None:
        pytest.skip(f"cannot emulate linux/arm64: {missing}")
    make_base = [str(ROOT / "docker" / "make_base_image.sh"), BASE, PLATFORM]
    subprocess.run(make_base, check=True, timeout=1200)
    build = docker(
        "build", "--network", "host", "--platform", PLATFORM, "--build-arg", f"BASE_IMAGE={BASE}",
        "-f", "docker/Dockerfile", "-t", TAG, str(ROOT), timeout=1200,
    )  # fmt: skip
    assert build.returncode == 0, build.stderr[-2000:]
    return TAG


def test_arm64_demo_is_healthy_under_emulation_with_ncnn(arm64_image):
    assert inspect(arm64_image)["Architecture"] == "arm64"
    port = free_port()
    container = run_detached(arm64_image, port, "--platform", PLATFORM)
    try:
        assert docker("exec", container, "uname", "-m").stdout.strip() == "aarch64"
        state = health(port, timeout=300)
        assert state["pipeline"]["running"] and state["model"]["loaded"], state
        deadline = time.time() + 300
        while state["pipeline"]["detection"]["detector_ms"] is None:  # NanoDet has not run yet
            assert time.time() < deadline, state["pipeline"]
            time.sleep(2)
            state = health(port)
        assert state["pipeline"]["error"] is None, state["pipeline"]
        chosen = docker(
            "exec", container, "python", "-c",
            "from models.detector.runtimes import choose_runtime as c; print(c('auto', False))",
        )  # fmt: skip
        assert chosen.stdout.strip() == "ncnn"
        wait_healthy(container, timeout=300)
        stop_cleanly(container)
    finally:
        docker("rm", "-f", container, check=False)
