"""A camera bumped while the real daemon runs repairs itself from people walking: /v1/health
first flags it, then says it re-learned, serves the repaired model and clears the alert."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import tests.e2e.test_camera_moved
from tests.e2e.server import running_server, wait_for
from tests.e2e.test_camera_moved import _bumped_scene, _references_ready_before_bump

pytestmark = pytest.mark.timeout(420)


def test_a_bumped_camera_is_repaired_and_the_alert_cleared(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # later than the alert test's bump: the references must be ready and people seen first
    monkeypatch.setattr(tests.e2e.test_camera_moved, "BUMP_S", 40.0)
    _bumped_scene(monkeypatch, camera=1)
    learning = {"enabled": True, "improve": False, "heal_min_positions": 60}
    with running_server(data_dir=tmp_path, learning=learning) as srv:
        _references_ready_before_bump(srv)
        flagged = wait_for(
            lambda: srv.get("/v1/health").json(),
            lambda h: h["cameras"][1]["alignment"]["moved"] and h["cameras"][1]["repair"],
            150,
            "camera 1 never flagged",
        )
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
        assert served["floor_prior"]["policy"] == "prior"
        wait_for(
            lambda: srv.get("/v1/health").json()["cameras"][1]["alignment"]["moved"],
            lambda moved: not moved,
            150,
            "the alert stayed after the repair",
        )
