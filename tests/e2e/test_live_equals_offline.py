"""The live daemon and offline ``momloc track`` run one chain: on the same recording they serve
the same snapshots, frame set by frame set.

A short synthetic scene is drawn into a recording (``momloc simulate --record`` does the same).
Offline: ``momloc track --smooth-s 0`` as a user runs it (a subprocess), which writes what the
live pipeline would have served. Live: the daemon as ``momloc serve`` builds it from settings
(``service.daemon.build_daemon``: its pipeline, hub, listeners, outputs), the recording's frame
sets fed to ``Pipeline.process`` by hand, so the clock is the recorded capture times, not the wall.
Both detect on every frame set (``detection.schedule: every_frame``; the live default ``auto``
detects when the CPU is free, which no comparison could repeat).

Compared exactly, not to a tolerance: both sides round positions to the same 4 decimals when the
snapshot is built and JSON carries those floats unchanged, and the chain has no randomness and no
wall-clock input; any difference is a difference of code path.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from capture.recording import Recording
from models.simulate import make_scene
from service.daemon import build_daemon
from service.demo import DEMO_PRESET, DEMO_SEED
from service.offline.record import record_scene
from service.settings import DEMO_MODEL_DIR, load_settings

pytestmark = pytest.mark.timeout(300)
ROOT = Path(__file__).resolve().parents[2]
FRAMES = 45  # 3 s at 15 fps: tracks are born, confirmed and move


def test_live_pipeline_and_momloc_track_serve_identical_snapshots(tmp_path):
    scene = make_scene(DEMO_PRESET, seed=DEMO_SEED, people=3, fps=15)
    rec = tmp_path / "rec"
    record_scene(scene, FRAMES, rec, progress=False)
    recording = Recording.open(rec)

    out = tmp_path / "positions.jsonl"
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOMLOC_")}
    args = ["track", rec, "--model", DEMO_MODEL_DIR, "--out", out, "--smooth-s", 0]
    result = subprocess.run(
        [sys.executable, "-m", "service.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=240,
        env={**env, "PYTHONPATH": str(ROOT)},
        cwd=ROOT,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    offline = [json.loads(line) for line in out.read_text().splitlines()]

    settings = load_settings(
        None,
        cameras=[{"type": "file", "path": str(c.video)} for c in recording.cameras],
        model_dir=DEMO_MODEL_DIR,
        detection={"schedule": "every_frame"},
    )
    daemon = build_daemon(settings)
    try:
        live = [
            daemon.pipeline.process(frame_set).as_dict() for _, frame_set in recording.frame_sets()
        ]
    finally:
        daemon.pipeline.stop()

    assert len(live) == len(offline) == len(recording)
    assert sum(len(s["people"]) for s in live) >= len(live), "nobody tracked: nothing compared"
    for frame, (served, tracked) in enumerate(zip(live, offline, strict=True)):
        assert tracked["frame"] == frame
        assert {k: served[k] for k in ("seq", "t", "people")} == {
            k: tracked[k] for k in ("seq", "t", "people")
        }, frame
