"""Issue 25, item 4: record, train and check are one state machine on the real daemon.

A user who clicks around the /setup page (or a script that posts at will) gets 409 with the step
that runs and how to end it; training learns from the recording as it was when it started,
whatever is written to the file meanwhile."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import httpx
import pytest

from models.simulate import simulate
from service.setup import training
from tests.e2e.server import running_server, wait_for

pytestmark = pytest.mark.timeout(300)
MARKS = [{"name": "A", "x": 2.0, "y": 2.0}, {"name": "B", "x": 4.0, "y": 3.0}]
CHECK = {"marks": MARKS, "seconds": 60, "move_seconds": 60, "countdown": 0}


def post(server, path: str, body: Any) -> httpx.Response:
    return httpx.post(server.http + path, json=body, timeout=30)


def status(server) -> dict[str, Any]:
    return server.get("/v1/setup/status").json()


def ready(server) -> None:
    """Every camera has delivered a frame (a collection needs the image sizes)."""
    sizes = server.daemon.pipeline
    wait_for(lambda: sizes.image_sizes, lambda s: None not in s, 120, "camera frames")


def refused(response: httpx.Response, *words: str) -> None:
    assert response.status_code == 409, response.text
    detail = response.json()["detail"]
    assert all(word in detail for word in words), detail


def test_a_step_that_conflicts_with_the_running_one_gets_409_with_the_reason(tmp_path):
    simulate("indoor-2cam", 60, seed=5).dataset.save(tmp_path / "rec.npz")
    with running_server() as server:
        server.setup.data_dir = tmp_path
        ready(server)
        try:
            # collecting: neither training nor a check may start, nor a second collection
            start = {"marks": MARKS, "seconds": 60, "countdown": 0, "out": "room.npz"}
            first = post(server, "/v1/setup/start", start)
            assert first.status_code == 200, first.text
            refused(post(server, "/v1/setup/verify", CHECK), "collection", "/v1/setup/stop")
            refused(post(server, "/v1/setup/train", {"recording": "rec.npz"}), "collection")
            refused(post(server, "/v1/setup/start", start), "already running")
            refused(post(server, "/v1/setup/record-again", {"mark": "A"}), "already running")
            assert status(server)["verify"]["state"] == "idle"
            assert status(server)["training"]["state"] == "idle"
            assert post(server, "/v1/setup/stop", {}).json()["state"] == "stopped"

            # training: no collection (it would change the data) and no check (the model changes)
            train = {"recording": "rec.npz", "epochs": 2000}
            assert post(server, "/v1/setup/train", train).status_code == 202
            again = {**start, "out": "other.npz"}
            refused(post(server, "/v1/setup/start", again), "training", "/v1/setup/train/cancel")
            refused(post(server, "/v1/setup/record-again", {"mark": "A"}), "training")
            refused(post(server, "/v1/setup/verify", CHECK), "training")
            refused(post(server, "/v1/setup/train", train), "already running")
            assert status(server)["state"] == "stopped"  # the collection did not start again
            assert not (tmp_path / "other.npz").exists()
            assert post(server, "/v1/setup/train/cancel", {}).status_code == 200
            cancelled = wait_for(
                lambda: status(server)["training"], lambda t: t["state"] != "running", 60, "cancel"
            )
            assert cancelled["error"] == "training cancelled"

            # checking: no collection, no training
            assert post(server, "/v1/setup/verify", CHECK).status_code == 200
            refused(post(server, "/v1/setup/start", again), "check", "/v1/setup/verify/stop")
            refused(post(server, "/v1/setup/train", train), "check")
            refused(post(server, "/v1/setup/verify", CHECK), "already running")
            assert post(server, "/v1/setup/verify/stop", {}).json()["state"] == "stopped"

            # idle again: any step may start
            assert post(server, "/v1/setup/start", again).status_code == 200
            assert post(server, "/v1/setup/stop", {}).json()["state"] == "stopped"
        finally:
            server.training.cancel()


def rows_trained_on(model_dir: Path) -> int:
    metrics = json.loads((model_dir / "model.json").read_text())["metrics"]
    return int(metrics["train_rows"] + metrics["val_rows"])


def test_training_learns_from_the_recording_as_it_was_when_it_started(tmp_path, monkeypatch):
    monkeypatch.setattr(training, "FIRST_MODEL_S", 2.0)  # a short first stage: both still run
    recording = tmp_path / "rec.npz"
    rows = simulate("indoor-2cam", 120, seed=5).dataset
    rows.save(recording)
    with running_server() as server:
        server.setup.data_dir = tmp_path
        server.wait_for_seq(3)
        try:
            body = {"recording": "rec.npz", "epochs": 5, "first_model": True}
            started = post(server, "/v1/setup/train", body)
            assert started.status_code == 202, started.text
            # meanwhile the file grows (``momloc collect`` into it from a terminal)
            simulate("indoor-2cam", 300, seed=6).dataset.save(recording)
            done = wait_for(
                lambda: status(server)["training"], lambda t: t["state"] != "running", 240, "train"
            )
            assert done["state"] == "done", done
        finally:
            server.training.cancel()
    assert rows_trained_on(tmp_path / "model.first") == rows.n  # the first stage
    assert rows_trained_on(tmp_path / "model") == rows.n  # the final stage: the same rows
    assert not (tmp_path / "model.recording").exists()  # the copy is gone with the run
