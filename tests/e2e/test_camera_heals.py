"""A camera bumped while the real daemon runs repairs itself from people walking: /v1/health
first flags it, then says it re-learned, serves the repaired model and clears the alert.

In lock-step (:class:`tests.e2e.server.LockstepRig`): scene frame i+1 is drawn once frame i is
processed, and the image check and the self-labeler (with it the repair) run inline, so every
run sees the same frames at the same scene times on a fast or a loaded machine (their worker
threads would drop frame sets when behind), and the minutes of walking the repair needs take as
long as the machine needs to process them (paced in real time: 2–5 minutes of wall time).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest

import service.daemon
import service.pipeline.listeners
import tests.e2e.test_camera_moved
from service.camera_health.image_shift import CameraShiftMonitor, ShiftWorker
from service.learning.listener import SelfLabeler
from tests.e2e.server import LockstepRig, RunningServer, running_server, wait_for
from tests.e2e.test_camera_moved import _bumped_scene

pytestmark = pytest.mark.timeout(420)

BUMP_S = 20.0  # scene seconds: the references are ready after ~2.5 s, people were labelled


def _inline_image_check(monitor: CameraShiftMonitor, *, threaded: bool = True) -> ShiftWorker:
    return ShiftWorker(monitor, threaded=False)


def _scene_s(srv: RunningServer) -> float:
    """Scene seconds of the newest snapshot (lock-step frames carry scene time)."""
    rig = srv.daemon.pipeline.rig
    assert isinstance(rig, LockstepRig)
    return srv.daemon.hub.latest().t - rig.t0


def test_a_bumped_camera_is_repaired_and_the_alert_cleared(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tests.e2e.test_camera_moved, "BUMP_S", BUMP_S)
    _bumped_scene(monkeypatch, camera=1)
    monkeypatch.setattr(service.pipeline.listeners, "ShiftWorker", _inline_image_check)
    inline_labels = functools.partial(SelfLabeler, threaded=False)
    monkeypatch.setattr(service.daemon, "SelfLabeler", inline_labels)
    learning = {"enabled": True, "improve": False, "heal_min_positions": 60}
    with running_server(data_dir=tmp_path, learning=learning, lockstep=True) as srv:
        ready = wait_for(
            lambda: srv.get("/v1/health").json(),
            lambda h: all(c["alignment"]["reference"] == "ready" for c in h["cameras"]),
            150,
            "image references never became ready",
        )
        assert _scene_s(srv) < BUMP_S and not ready["cameras"][1]["alignment"]["moved"]
        flagged = wait_for(
            lambda: srv.get("/v1/health").json(),
            lambda h: h["cameras"][1]["alignment"]["moved"] and h["cameras"][1]["repair"],
            150,
            "camera 1 never flagged",
        )
        assert _scene_s(srv) >= BUMP_S
        assert "re-learning from people walking" in flagged["cameras"][1]["repair"]
        repaired = wait_for(
            lambda: srv.get("/v1/health").json(),
            lambda h: any(r["state"] == "repaired" for r in h["learning"]["repairs"]),
            300,
            "camera 1 never repaired",
        )
        repair = next(r for r in repaired["learning"]["repairs"] if r["state"] == "repaired")
        assert repair["camera"] == 1 and repair["positions"] >= 60
        assert repair["error_m"] <= 1.25 * repair["reachable_m"]
        assert "camera 1 moved at" in repair["message"] and "re-learned from" in repair["message"]
        assert srv.daemon.pipeline.model_dir == tmp_path / "model"
        served = json.loads((tmp_path / "model" / "model.json").read_text())
        # repaired as the camera's image turned (models.mom.image_transform), the maps kept
        assert served["image_transforms"][0] is None and served["image_transforms"][1]
        assert "(its image turned)" in repair["message"]
        wait_for(
            lambda: srv.get("/v1/health").json()["cameras"][1]["alignment"]["moved"],
            lambda moved: not moved,
            150,
            "the alert stayed after the repair",
        )
