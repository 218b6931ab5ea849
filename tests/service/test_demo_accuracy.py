"""Regression gates: the demo scene through the real pipeline, deterministic (no wall clock).

``service.demo.replay_demo`` runs the demo daemon frame by frame with scene timestamps: boxes ->
association -> shipped demo model -> tracker, scored against the simulator's truth (people whose
true box is at least half inside a camera's image; reported people matched one-to-one within
1 m). Recorded on the shipped model (seed 7, 3 people, frames 30..599 for simulated boxes,
30..329 for the drawn frames through NanoDet), see bench/results/demo_scene.md: the bounds leave a
margin for retraining, not for a blinder detector or a worse drawing.

Simulated boxes are scored under the former kind noise (``ideal``, pinned on purpose: it
isolates the pipeline's and model's own behaviour from the detector) and under the measured
default profile (``nanodet``: what ``momloc demo --detections simulated`` shows).
"""

from __future__ import annotations

from service.demo import DEMO_PRESET, demo_settings, replay_demo

# The walking gates below score the demo's cameras and model on the walkers alone (the recorded
# figures); the demo itself also seats a person on the sofa (DEMO_SCENE), scored at the end.


def test_demo_scene_with_simulated_boxes_under_kind_noise():
    score = replay_demo(
        demo_settings(detections="simulated", profile="ideal", scene=DEMO_PRESET), frames=600
    )
    s = score.summary()
    # recorded: mean 0.117 m, median 0.087 m, 97.7 % within 0.5 m, recall 1.0, precision 1.0, 3 ids
    assert s["median_m"] < 0.15 and s["mean_m"] < 0.16, s
    assert s["within_0.5m"] > 0.93 and s["recall"] > 0.95 and s["precision"] > 0.95, s
    assert s["ids"] <= 6, s


def test_demo_scene_with_simulated_boxes_as_blind_as_the_shipped_detector():
    score = replay_demo(
        demo_settings(detections="simulated", profile="nanodet", scene=DEMO_PRESET), frames=600
    )
    s = score.summary()
    # 2026-12-02 (RECOMMENDED with coasting served 0.5 s, likelihood assignment, see
    # service/tracking/tracker.py, and service.tracking.view_bias): mean 0.259 m, median 0.186 m,
    # 85.9 %, recall 0.917, precision 0.83, 7 ids; bounds kept. Recorded 2026-12-01 with the
    # daemon's tracker fed covariances and coverage (service.tracking.tracker.RECOMMENDED): mean
    # 0.272 m, median 0.194 m, 83.9 % within 0.5 m, recall 0.857, precision 0.690, 10 ids. With the
    # former tracker: mean 0.299 m, median 0.249 m, 82.1 %, recall 0.933, precision 0.677 (tracks on
    # the profile's lasting false boxes), 13 ids; recall is lower now because a person only one
    # camera reports where the other should see them waits 1 s (and 0.5 s of doubt hides them), the
    # price of fewer ghosts.
    assert s["median_m"] < 0.23 and s["mean_m"] < 0.3, s
    assert s["within_0.5m"] > 0.8 and s["recall"] > 0.82 and s["precision"] > 0.65, s
    assert s["ids"] <= 13, s


def test_demo_scene_with_drawn_frames_through_the_shipped_detector():
    """The default demo: NanoDet on the drawn frames, the demo model trained on its boxes."""
    score = replay_demo(demo_settings(detections="rendered", scene=DEMO_PRESET), frames=330)
    s = score.summary()
    # recorded: mean 0.108 m, median 0.065 m, 95.8 % within 0.5 m, recall 1.0, precision 0.841
    # (coasting tracks, see bench/results/demo_scene.md), 5 ids; frames 30..599: 0.089 m mean,
    # precision 0.906
    assert s["median_m"] < 0.1 and s["mean_m"] < 0.14, s
    assert s["within_0.5m"] > 0.92 and s["recall"] > 0.95 and s["precision"] > 0.78, s
    assert s["ids"] <= 8, s


def test_demo_scene_serves_the_person_on_the_sofa() -> None:
    """The demo as it plays (issue 27): three walkers and one person seated on the sofa behind
    the coffee table the whole time, served seated (the demo model's height model reads the
    posture; bench/results/postures.md, demo-lounge)."""
    score = replay_demo(demo_settings(detections="simulated", profile="ideal"), frames=300)
    s = score.summary()
    # recorded 2026-12-03 with the rebuilt demo model (frames 30..299, ideal): mean 0.112 m,
    # median 0.068 m, 96.3 % within 0.5 m, recall 0.937, precision 0.985, 4 ids; frames 30..599:
    # mean 0.102 m, 98.0 %, recall 0.967. With the former model (no set-up area, no posture):
    # mean 0.189 m, median 0.106 m, 87.4 %, recall 0.957, precision 0.80. The walkers alone
    # (above): mean 0.117 m, 97.7 %, precision 1.0
    assert s["recall"] > 0.9 and s["precision"] > 0.9, s
    assert s["median_m"] < 0.1 and s["within_0.5m"] > 0.93, s
