"""The Docker image for real: build it, run it with no config (the demo) and with a mounted config
and model, and check from the host what a user relies on: /v1/health answers, the HEALTHCHECK
turns healthy, the daemon runs as the non-root user, and `docker stop` ends it cleanly within the
grace period.

Opt-in (``make test-docker`` sets MOMLOC_DOCKER_TESTS=1): the first build takes minutes. Skipped
with the reason where no Docker engine can run. No registry is needed: the Dockerfile's base
image is built from Debian packages (``docker/make_base_image.sh``). Containers use the host's
network, as the engine may run without a bridge (``--bridge=none``) on CI.
"""

from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

import httpx
import pytest

from service.settings import DEMO_MODEL_DIR
from tests.e2e.docker_engine import (
    docker,
    free_port,
    health,
    inspect,
    require_engine,
    run_detached,
    stop_cleanly,
    wait_healthy,
)

pytestmark = [pytest.mark.docker, pytest.mark.timeout(1800)]
ROOT = Path(__file__).resolve().parents[2]
TAG = "momloc:test"


@pytest.fixture(scope="module")
def image() -> str:
    require_engine()
    subprocess.run([str(ROOT / "docker" / "make_base_image.sh")], check=True, timeout=1200)
    build = docker("build", "--network", "host", "-f", "docker/Dockerfile", "-t", TAG, str(ROOT))
    assert build.returncode == 0, build.stderr[-2000:]
    return TAG


def test_demo_container_is_healthy_non_root_and_stops_cleanly(image):
    port = free_port()
    container = run_detached(image, port)
    try:
        state = health(port)
        assert state["pipeline"]["running"] and state["model"]["loaded"], state
        wait_healthy(container)
        assert docker("exec", container, "id", "-u").stdout.strip() == "1000"
        assert inspect(container)["Config"]["User"] == "momloc"
        stop_cleanly(container)
    finally:
        docker("rm", "-f", container, check=False)


def test_container_with_a_mounted_config_and_model(image, tmp_path):
    model = tmp_path / "model"
    shutil.copytree(DEMO_MODEL_DIR, model)
    config = tmp_path / "momloc.yaml"
    config.write_text(
        "cameras: [{type: synthetic, index: 0}, {type: synthetic, index: 1}]\n"
        "model_dir: /model\ntoken: s3cret\n"
    )
    port = free_port()
    container = run_detached(
        image,
        port,
        "-e",
        "MOMLOC_TOKEN=s3cret",  # the HEALTHCHECK sends it
        "-v",
        f"{config}:/config/momloc.yaml:ro",
        "-v",
        f"{model}:/model:ro",
    )
    try:
        deadline = time.time() + 120
        while True:
            try:
                answer = httpx.get(
                    f"http://127.0.0.1:{port}/v1/health",
                    headers={"Authorization": "Bearer s3cret"},
                    timeout=5,
                )
                break
            except httpx.HTTPError:
                assert time.time() < deadline, docker("logs", container).stderr[-2000:]
                time.sleep(0.5)
        assert answer.status_code == 200 and answer.json()["model"]["path"] == "/model"
        assert httpx.get(f"http://127.0.0.1:{port}/v1/health", timeout=5).status_code == 401
        wait_healthy(container)
        stop_cleanly(container)
    finally:
        docker("rm", "-f", container, check=False)
