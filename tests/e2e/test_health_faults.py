"""Issue 25, item 6: faults are reported as they are, on the real daemon.

A disk that fills up during a set-up recording: the status counts the rows on disk (not the
rows the collector meant to write), ``/v1/health`` names the failure and the log has it once.
An MQTT broker that is down: ``/v1/health`` says ``degraded`` and which output."""

from __future__ import annotations

import errno
import logging
from pathlib import Path
from typing import Any

import httpx
import pytest

import models.data.dataset
from common.atomic import atomic_write
from models.data.dataset import MomDataset
from service.api.server import serve_in_thread
from service.daemon import build_daemon
from service.settings import DEMO_MODEL_DIR, load_settings
from tests.e2e.mqtt_broker import Broker, ensure_mosquitto, free_port
from tests.e2e.server import running_server, wait_for

pytestmark = pytest.mark.timeout(300)


class FillingDisk:
    """``atomic_write`` on a disk with room for ``room`` saves of ``name``: the next one fails
    like a full disk does (ENOSPC while writing; the real atomic_write removes its temporary
    file and leaves the previous file as it was)."""

    def __init__(self, name: str, room: int) -> None:
        self.name, self.room, self.saves, self.refused = name, room, 0, 0

    def __call__(self, path: Any, produce: Any, *args: Any) -> Path:
        if Path(path).name != self.name:
            return atomic_write(path, produce, *args)
        if self.saves >= self.room:
            self.refused += 1

            def produce_on_full_disk(tmp: Path) -> None:
                raise OSError(errno.ENOSPC, "No space left on device", str(tmp))

            return atomic_write(path, produce_on_full_disk, *args)
        self.saves += 1
        return atomic_write(path, produce, *args)


def test_a_full_disk_during_recording_is_reported_with_the_rows_on_disk(
    tmp_path, monkeypatch, caplog
):
    disk = FillingDisk("room.npz", room=2)
    monkeypatch.setattr(models.data.dataset, "atomic_write", disk)
    caplog.set_level(logging.INFO)
    with running_server(people=1) as server:
        server.setup.data_dir = tmp_path
        pipeline = server.daemon.pipeline
        wait_for(lambda: pipeline.image_sizes, lambda s: None not in s, 120, "camera frames")
        start = {
            "marks": [{"name": "A", "x": 3.0, "y": 3.0}],
            "seconds": 20, "countdown": 0, "move_seconds": 0, "out": "room.npz",
        }  # fmt: skip
        response = httpx.post(server.http + "/v1/setup/start", json=start, timeout=30)
        assert response.status_code == 200, response.text
        status = wait_for(
            lambda: server.get("/v1/setup/status").json(),
            lambda s: s["state"] != "running",
            120,
            "recording",
        )
        health = server.get("/v1/health").json()
    on_disk = MomDataset.load(tmp_path / "room.npz").n
    assert disk.saves == 2 and disk.refused >= 1
    assert status["state"] == "failed", status
    assert "No space left on device" in status["error"] and "room.npz" in status["error"]
    assert status["new_rows"] == on_disk == status["total_rows"] > 0, (status, on_disk)
    assert status["unsaved_rows"] > 0 and f"{on_disk} new rows are on disk" in status["error"]
    assert health["degraded"]["setup_recording"] == status["error"], health["degraded"]
    assert health["status"] == "degraded"
    logged = [r for r in caplog.records if "No space left on device" in r.getMessage()]
    assert len(logged) == 1 and logged[0].levelno == logging.ERROR, logged


def mqtt_daemon(port: int) -> Any:
    """The demo scene's daemon publishing to an MQTT broker at ``port`` (real uvicorn)."""
    settings = load_settings(
        None,
        cameras=[{"type": "synthetic", "index": 0}, {"type": "synthetic", "index": 1}],
        model_dir=DEMO_MODEL_DIR,
        synthetic={"preset": "indoor-2cam", "seed": 7, "people": 1, "fps": 30.0},
        mqtt={
            "host": "127.0.0.1", "port": port, "room": f"down{port}",
            "reconnect_min_s": 0.2, "reconnect_max_s": 1.0,
        },
    )  # fmt: skip
    return serve_in_thread(build_daemon(settings))


def health_of(background: Any) -> dict[str, Any]:
    return httpx.get(f"http://127.0.0.1:{background.port}/v1/health", timeout=30).json()


def test_health_is_degraded_and_names_mqtt_while_the_broker_is_down():
    port = free_port()  # nothing listens there: the broker is down
    background = mqtt_daemon(port)
    try:
        health = wait_for(
            lambda: health_of(background),
            lambda h: h["mqtt"]["error"] is not None,
            60,
            "a failed connection attempt",
        )
    finally:
        background.stop()
    assert health["status"] == "degraded", health
    reason = health["degraded"]["mqtt"]
    assert f"127.0.0.1:{port}" in reason and "not connected" in reason, reason
    assert health["mqtt"]["connected"] is False


def test_health_follows_a_broker_that_goes_down_and_comes_back():
    broker = Broker(ensure_mosquitto()).start()
    background = mqtt_daemon(broker.port)
    try:
        up = wait_for(
            lambda: health_of(background), lambda h: h["mqtt"]["connected"], 60, "connected"
        )
        assert "mqtt" not in up["degraded"], up["degraded"]
        broker.stop()
        down = wait_for(
            lambda: health_of(background), lambda h: "mqtt" in h["degraded"], 60, "degraded"
        )
        assert down["status"] == "degraded" and f":{broker.port}" in down["degraded"]["mqtt"]
        broker.start()  # same port
        back = wait_for(
            lambda: health_of(background), lambda h: h["mqtt"]["connected"], 60, "reconnected"
        )
        assert "mqtt" not in back["degraded"], back["degraded"]
    finally:
        background.stop()
        broker.close()
