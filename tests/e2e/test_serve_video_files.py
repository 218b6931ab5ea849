"""`momloc serve` path on recorded video: capture workers -> real detector -> model -> API."""

from __future__ import annotations

import asyncio
import json

import cv2
import numpy as np
import pytest
import websockets

from models.simulate import make_scene
from service.api.server import serve_in_thread
from service.daemon import build_daemon
from service.demo import DEMO_PRESET, DEMO_SEED
from service.settings import DEMO_MODEL_DIR, load_settings

pytestmark = pytest.mark.timeout(240)
FRAMES = 45


def write_clips(tmp_path) -> list:
    """Two cameras' views of the demo scene as MJPG .avi files (what a webcam recording gives)."""
    scene = make_scene(DEMO_PRESET, seed=DEMO_SEED, people=3, fps=15)
    paths = []
    for k in range(2):
        path = tmp_path / f"cam{k}.avi"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 15, (640, 480))
        for i in range(FRAMES):
            writer.write(scene.render(i, k))
        writer.release()
        paths.append(path)
    return paths


def test_serve_on_video_files_with_the_real_detector(tmp_path):
    cam0, cam1 = write_clips(tmp_path)
    config = tmp_path / "momloc.yaml"
    config.write_text(
        f"cameras:\n  - {{type: file, path: {cam0}}}\n  - {{type: file, path: {cam1}}}\n"
        "detector: {score_threshold: 0.4}\n"
        f"model_dir: {DEMO_MODEL_DIR}\n"  # the clips are drawn from the demo model's room
    )
    settings = load_settings(config)
    background = serve_in_thread(build_daemon(settings))
    try:
        url = f"ws://127.0.0.1:{background.port}/v1/stream"

        async def collect() -> list[dict]:
            """Snapshots until 10 people (one seen by both cameras) came through, or 120 s:
            on a loaded machine the detector thread (nice 10, beside the pipeline) runs less
            often, so a fixed number of snapshots would make the outcome depend on the load."""
            messages: list[dict] = []
            loop = asyncio.get_running_loop()
            deadline = loop.time() + 120
            async with websockets.connect(url) as ws:
                while loop.time() < deadline:
                    messages.append(json.loads(await asyncio.wait_for(ws.recv(), 20)))
                    people = [p for m in messages for p in m["people"]]
                    both = any(sorted(p["cameras"]) == [0, 1] for p in people)
                    if len(messages) >= 45 and len(people) >= 10 and both:
                        break
            return messages

        messages = asyncio.run(collect())
        daemon = background.daemon
        health = daemon.health()
        assert [c["name"] for c in health["cameras"]] == ["cam0.avi", "cam1.avi"]
        assert all(c["connected"] for c in health["cameras"]), health["cameras"]
        assert health["pipeline"]["stage_ms"]["detect"] > 0
        people = [p for m in messages for p in m["people"]]
        assert len(people) >= 10, "the detector found (almost) nobody in the recorded frames"
        xy = np.array([[p["x"], p["y"]] for p in people])
        # Inside the 10 x 10 m room (+ margin). A real detector's occasional false or cut box seen
        # by one camera can land outside (2026-12-01: one of ~60 positions at 12.2, 11.1 m with
        # NanoDet), so the check is on the share, not on every position.
        inside = np.all((xy > -1.0) & (xy < 11.0), axis=1)
        assert inside.mean() >= 0.9, xy[~inside]
        assert any(sorted(p["cameras"]) == [0, 1] for p in people)  # matched across cameras
    finally:
        background.stop()
