"""Regression gate: the demo scene through the real pipeline, deterministic (no wall clock).

Simulated boxes -> association -> shipped demo model -> tracker, frame by frame with scene
timestamps. Recorded on the shipped model (seed 7, 3 people, 600 frames = 20 s): median error
0.09 m, 97 % within 0.5 m, 3 ids (one per person). The bounds leave a margin for retraining.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import linear_sum_assignment

from capture.rig import FrameSet
from service.daemon import build_daemon
from service.demo import demo_settings


def test_demo_scene_accuracy_and_ids():
    daemon = build_daemon(demo_settings(detections="simulated"))
    daemon.pipeline.rig.render_every = 0  # boxes only: no drawing needed
    pipeline, rig = daemon.pipeline, daemon.pipeline.rig
    errors, reported, visible, ids = [], 0, 0, set()
    for i in range(600):
        frames = [dataclasses.replace(f, timestamp=1e6 + i / 30) for f in rig.produce(i).frames]
        snapshot = pipeline.process(FrameSet(frames, 0.0))
        if i < 30:  # tracks confirmed
            continue
        truth = rig.observation(i)
        gt = truth.world[np.isfinite(truth.boxes).all(axis=2).any(axis=1), :2]
        got = np.array([[p["x"], p["y"]] for p in snapshot.people]).reshape(-1, 2)
        reported, visible = reported + len(got), visible + len(gt)
        ids |= {p["id"] for p in snapshot.people}
        if len(got) and len(gt):
            cost = np.linalg.norm(got[:, None] - gt[None], axis=2)
            rows, cols = linear_sum_assignment(cost)
            errors.extend(cost[rows, cols])
    errors = np.array(errors)
    assert 0.9 * visible <= reported <= 1.15 * visible, (reported, visible)
    assert np.median(errors) < 0.15, np.median(errors)
    assert np.mean(errors < 0.5) > 0.93, np.mean(errors < 0.5)
    assert len(ids) <= 6, ids
