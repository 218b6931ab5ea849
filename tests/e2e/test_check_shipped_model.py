"""Issue 25, item 3: the check step never writes into the shipped demo model.

``POST /v1/setup/verify`` on the demo daemon (the real server on loopback, the model shipped in
the package) used to rewrite ``models/demo_model/model.json``. Its result now goes to the daemon's
``data_dir`` and is read back from there: in ``/v1/health`` (what the map and the set-up page
show), also by the next daemon on the same ``data_dir``.
"""

from __future__ import annotations

import time
from pathlib import Path

import httpx
import pytest

from service.settings import DEMO_MODEL_DIR
from tests.e2e.server import RunningServer, running_server

pytestmark = pytest.mark.timeout(180)
SHIPPED = DEMO_MODEL_DIR / "model.json"


def check(server: RunningServer) -> dict:
    """Press Check for one mark and wait for the result."""
    body = {"marks": [{"name": "M", "x": 5.0, "y": 5.0}], "seconds": 2, "move_seconds": 0,
            "countdown": 0}  # fmt: skip
    started = httpx.post(
        server.http + "/v1/setup/verify", json=body, headers=server.headers(), timeout=30
    )
    assert started.status_code == 200, started.text
    deadline = time.time() + 60
    while (status := server.get("/v1/setup/status").json()["verify"])["state"] == "running":
        assert time.time() < deadline, status
        time.sleep(0.2)
    assert status["state"] == "done", status
    return status


def test_check_on_the_demo_keeps_the_shipped_model_and_shows_the_result(tmp_path, monkeypatch):
    data_dir = tmp_path / "data"
    monkeypatch.setenv("MOMLOC_DATA_DIR", str(data_dir))
    before = SHIPPED.read_bytes()
    try:
        with running_server() as server:
            server.wait_for_seq(5)
            status = check(server)
            summary = status["summary"]
            assert summary["marks"] == 1 and status["marks"][0]["samples"] > 0, status
            assert Path(status["stored_in"]).parent == data_dir / "checks"
            shown = server.get("/v1/health").json()["model"]["verification"]
            assert shown == summary
        assert SHIPPED.read_bytes() == before, "the check rewrote the shipped model.json"

        with running_server() as again:  # the next start on the same data_dir shows it too
            assert again.get("/v1/health").json()["model"]["verification"] == summary
    finally:
        if SHIPPED.read_bytes() != before:  # the code before the fix rewrote it: put it back
            SHIPPED.write_bytes(before)
