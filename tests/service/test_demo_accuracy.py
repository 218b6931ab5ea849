"""Regression gate: the demo scene through the real pipeline, deterministic (no wall clock).

Simulated boxes -> association -> shipped demo model -> tracker, frame by frame with scene
timestamps (seed 7, 3 people, 600 frames = 20 s), scored against everyone in view of a camera.

Two gates, recorded on the shipped demo model (2026-12-01):

- ``nanodet`` (the default detector profile: what a user of ``momloc demo`` gets): median error
  0.260 m, 74.8 % within 0.5 m, 1.41 reported people per person in view (tracks on the
  detector's lasting false boxes, 0.275 per camera and frame as measured on real video), 14 ids.
  The demo model was trained on the former kind noise, so these figures are what the harsher,
  measured detector costs it.
- ``ideal`` (the former kind noise, pinned on purpose: it isolates the pipeline's and model's own
  behaviour from the detector): median 0.091 m, 97.3 % within 0.5 m, 1.00 reported per person
  in view, 3 ids (one per person).

The bounds leave a margin for retraining.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from capture.rig import FrameSet
from service.daemon import build_daemon
from service.demo import demo_settings

# profile: (reported / in view low, high, median error <, share within 0.5 m >, ids <=)
GATES = {
    "nanodet": (1.0, 1.7, 0.31, 0.69, 18),
    "ideal": (0.9, 1.15, 0.15, 0.93, 6),
}


@pytest.mark.parametrize("profile", sorted(GATES))
def test_demo_scene_accuracy_and_ids(profile: str) -> None:
    settings = demo_settings(
        detections="simulated", profile=profile if profile != "nanodet" else None
    )
    assert settings.synthetic.detector_profile == profile  # nanodet: the default
    daemon = build_daemon(settings)
    daemon.pipeline.rig.render_every = 0  # boxes only: no drawing needed
    pipeline, rig = daemon.pipeline, daemon.pipeline.rig
    errors, reported, in_view, ids = [], 0, 0, set()
    for i in range(600):
        frames = [dataclasses.replace(f, timestamp=1e6 + i / 30) for f in rig.produce(i).frames]
        snapshot = pipeline.process(FrameSet(frames, 0.0))
        if i < 30:  # tracks confirmed
            continue
        truth = rig.observation(i)
        gt = truth.world[np.isfinite(truth.true_boxes).all(axis=2).any(axis=1), :2]
        got = np.array([[p["x"], p["y"]] for p in snapshot.people]).reshape(-1, 2)
        reported, in_view = reported + len(got), in_view + len(gt)
        ids |= {p["id"] for p in snapshot.people}
        if len(got) and len(gt):
            cost = np.linalg.norm(got[:, None] - gt[None], axis=2)
            rows, cols = linear_sum_assignment(cost)
            errors.extend(cost[rows, cols])
    errors = np.array(errors)
    low, high, median, within, most_ids = GATES[profile]
    assert low * in_view <= reported <= high * in_view, (reported, in_view)
    assert np.median(errors) < median, np.median(errors)
    assert np.mean(errors < 0.5) > within, np.mean(errors < 0.5)
    assert len(ids) <= most_ids, ids
