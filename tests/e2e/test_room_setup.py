"""End to end, the calibration-free set-up as a user runs it on the synthetic room:
``momloc collect`` at floor marks -> ``momloc train`` -> the running daemon picks the new model up
from its watched model directory without dropping the WebSocket client -> positions follow the
simulated people. And the same collection driven from the ``/setup`` page's REST endpoints."""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
import websockets
from scipy.optimize import linear_sum_assignment

from models.data.dataset import MomDataset
from models.mom.runtime import MomRuntime
from service.demo import DEMO_SEED
from service.settings import DEMO_MODEL_DIR
from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(600)


def momloc(*args: str) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "service.cli", *args], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr[-2000:]


def install_model(source: Path, target: Path) -> None:
    """Copy a model into the watched directory the way a trainer would: atomic renames."""
    for name in ("encoder.onnx", "model.json"):
        shutil.copy(source / name, target / f".{name}.tmp")
        os.replace(target / f".{name}.tmp", target / name)


def matched_errors(messages: list[dict], rig) -> np.ndarray:
    errors = []
    for m in messages:
        truth = rig.scene.observe(rig.index_at(m["t"]))
        seen = np.isfinite(truth.boxes).all(axis=2).any(axis=1)
        got = np.array([[p["x"], p["y"]] for p in m["people"]]).reshape(-1, 2)
        if len(got) and seen.any():
            cost = np.linalg.norm(got[:, None] - truth.world[seen, None, :2].swapaxes(0, 1), axis=2)
            rows, cols = linear_sum_assignment(cost)
            errors.extend(cost[rows, cols])
    return np.array(errors)


def test_collect_train_hot_reload_stream(tmp_path: Path) -> None:
    marks, model = tmp_path / "marks.npz", tmp_path / "trained"
    momloc(
        "collect", "--source", "synthetic", "--preset", "indoor-2cam", "--seed", str(DEMO_SEED),
        "--grid", "3x3", "--seconds", "6", "--out", str(marks),
    )  # fmt: skip
    # With the measured default detector profile (nanodet) collect keeps 519 of 810 frames
    # (2026-12-01; > 80 % under the former kind noise): misses and false boxes drop the rest.
    assert MomDataset.load(marks).n > 9 * 6 * 15 * 0.5
    momloc("train", str(marks), "--out", str(model), "--epochs", "15", "--quiet")
    assert json.loads((model / "model.json").read_text())["floor_prior"]["policy"] == "prior"

    live = tmp_path / "live-model"
    live.mkdir()
    install_model(DEMO_MODEL_DIR, live)
    with running_server(model_dir=live) as server:
        server.wait_for_seq(5)
        assert server.daemon.watcher is not None
        server.daemon.watcher.interval_s = 0.2
        before = server.daemon.pipeline.runtime

        async def follow() -> tuple[list[dict], list[dict]]:
            async with websockets.connect(server.ws + "/v1/stream") as ws:
                first = [json.loads(await ws.recv()) for _ in range(10)]
                install_model(model, live)
                deadline = time.time() + 30
                while server.daemon.pipeline.runtime is before:
                    assert time.time() < deadline, server.get("/v1/health").json()
                    await ws.recv()  # keep reading: the same connection carries on
                after = [json.loads(await ws.recv()) for _ in range(90)]
                return first, after

        first, after = asyncio.run(follow())
        assert after[0]["seq"] > first[-1]["seq"]
        health = server.get("/v1/health").json()
        assert health["model_reload"]["ok"] and health["model"]["path"] == str(live)
        runtime = server.daemon.pipeline.runtime
        assert isinstance(runtime, MomRuntime) and runtime.policy == "prior"
        errors = matched_errors(after[30:], server.daemon.pipeline.rig)
        # What a user gets with the measured default detector profile (nanodet), 6 s per mark:
        # median 0.58-0.62 m, 27-45 % within 0.5 m, in three runs on 2026-12-02 (which frames
        # the window holds depends on the machine's load; 0.94 and 1.52 m, 23 % before the floor
        # prior left out boxes that are not the person at a mark: static false positives and feet
        # cut at the border, models/geometry/mark_fit.py).
        assert errors.size > 50 and np.median(errors) < 0.9, np.median(errors)
        assert np.mean(errors < 0.5) > 0.2, np.mean(errors < 0.5)


def test_setup_page_collects_from_the_running_daemon(tmp_path: Path) -> None:
    with running_server(people=1) as server:
        server.setup.data_dir = tmp_path
        server.wait_for_seq(5)
        deadline = time.time() + 20
        while None in server.daemon.pipeline.image_sizes:  # previews carry the frame size
            assert time.time() < deadline
            time.sleep(0.05)
        page = server.get("/setup")
        assert page.status_code == 200 and "Set up your room" in page.text
        body = {
            "grid": "2x2", "room": "10x10", "seconds": 1.0, "countdown": 0.2,
            "move_seconds": 0.2, "out": "web.npz",
        }  # fmt: skip
        started = httpx.post(server.http + "/v1/setup/start", json=body, timeout=10)
        assert started.status_code == 200, started.text
        again = httpx.post(server.http + "/v1/setup/start", json=body, timeout=10)
        assert again.status_code == 409  # one collection at a time
        deadline = time.time() + 60
        while (status := server.get("/v1/setup/status").json())["state"] == "running":
            assert time.time() < deadline, status
            time.sleep(0.2)
        assert status["state"] == "done", status
        assert status["new_rows"] > 10 and MomDataset.load(tmp_path / "web.npz").n > 10
        bad = httpx.post(server.http + "/v1/setup/start", json={**body, "out": "../x.npz"})
        assert bad.status_code == 422 and "plain file name" in bad.json()["detail"]
