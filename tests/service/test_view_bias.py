"""Lone-view bias compensation (service.tracking.view_bias): sign, per-camera keys, fading, tracker
use."""

from __future__ import annotations

import numpy as np
import pytest

from capture.rig import FrameSet
from models.detector.base import Detections
from service.stages import Association, Origin
from service.tracking.tracker import RECOMMENDED, Tracker
from service.tracking.view_bias import ViewBias, lone_view_positions
from tests.service.fake_frames import FunctionStage, NoRig, frames_at
from tests.service.mom_doubles import ModelDouble

BIAS = {0: np.array([0.4, -0.1]), 1: np.array([-0.3, 0.25])}  # each camera's lone-view error
FPS = 15.0


class BiasedViews(ModelDouble):
    """A localizer double: a box [x, y, x + 1, y + 1] encodes the true floor position; two
    views localize it exactly, one view alone is off by that camera's ``BIAS``."""

    num_cameras = 2
    image_sizes = np.array([[640, 480], [640, 480]])

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 4)
        out = np.full((len(boxes), 2), np.nan)
        for i, row in enumerate(boxes):
            seen = [k for k in range(2) if np.isfinite(row[k]).all()]
            if len(seen) == 2:
                out[i] = row[0, :2]
            elif len(seen) == 1:
                out[i] = row[seen[0], :2] + BIAS[seen[0]]
        return out

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        """Zero where seen (the pipeline's camera-moved check reads it)."""
        seen = np.isfinite(np.asarray(boxes, dtype=np.float64)).all(axis=-1)
        return np.where(seen, 0.0, np.nan)


def person(truth: np.ndarray, cameras: list[int], runtime: BiasedViews) -> Association:
    boxes = np.full((2, 4), np.nan, dtype=np.float32)
    for k in cameras:
        boxes[k] = [truth[0], truth[1], truth[0] + 1, truth[1] + 1]
    world = runtime.localize(boxes[None])[0]
    return Association(
        boxes, list(cameras), world, 0.0, [0 if k in cameras else None for k in (0, 1)]
    )


def step(bias: ViewBias, tracker: Tracker, t: float, people: list[Association], runtime):
    origins = [Origin(cameras=tuple(a.cameras), association=i) for i, a in enumerate(people)]
    positions = np.array([a.world[:2] for a in people], float).reshape(-1, 2)
    tracks = tracker.update(t, bias.correct(t, people, positions, runtime), origins)
    bias.learn(t, people, runtime, tracks)
    return tracks


def test_lone_view_positions_localize_each_box_alone():
    runtime = BiasedViews()
    truth = np.array([2.0, 3.0])
    lone = lone_view_positions([person(truth, [0, 1], runtime)], runtime)
    assert set(lone[0]) == {0, 1}
    for k in (0, 1):
        np.testing.assert_allclose(lone[0][k], truth + BIAS[k], atol=1e-6)


def test_single_view_position_is_corrected_towards_the_fused_one():
    """Two cameras for 3 s, then camera 0 alone: the correction removes most of camera 0's
    lone-view error. A wrong sign would double it (error 2 × 0.41 m)."""
    runtime = BiasedViews()
    bias, tracker = ViewBias(), Tracker(fps_hint=FPS, **RECOMMENDED)
    truth = np.array([2.0, 3.0])
    frames = int(3 * FPS)
    for i in range(frames):
        step(bias, tracker, i / FPS, [person(truth, [0, 1], runtime)], runtime)
    t = frames / FPS
    lone = person(truth, [0], runtime)
    corrected = bias.correct(t, [lone], lone.world[None], runtime)[0]
    raw_error = np.linalg.norm(lone.world - truth)
    assert raw_error == pytest.approx(np.linalg.norm(BIAS[0]))
    assert np.linalg.norm(corrected - truth) < 0.25 * raw_error
    assert np.dot(corrected - lone.world, BIAS[0]) < 0  # moved against the bias


def test_offsets_are_per_camera_and_the_served_track_stays_put():
    """Camera 1's lone view is corrected with camera 1's offset (not camera 0's, which points
    elsewhere), and the served position moves far less than the lone view's error when the
    second camera drops out; without the correction it follows the lone view."""
    runtime = BiasedViews()
    bias, tracker = ViewBias(), Tracker(fps_hint=FPS, **RECOMMENDED)
    truth = np.array([1.0, 4.0])
    frames = int(3 * FPS)
    for i in range(frames):
        tracks = step(bias, tracker, i / FPS, [person(truth, [0, 1], runtime)], runtime)
    before = np.array([tracks[0].x, tracks[0].y])
    for i in range(frames, frames + int(2 * FPS)):
        tracks = step(bias, tracker, i / FPS, [person(truth, [1], runtime)], runtime)
    after = np.array([tracks[0].x, tracks[0].y])
    assert len(tracks) == 1
    # 2 s later the offset has faded to ~2/3 (a 3 s time constant, 0.5 s prior)
    error = np.linalg.norm(BIAS[1])
    assert np.linalg.norm(after - truth) < 0.4 * error
    assert np.linalg.norm(after - before) < 0.4 * error

    plain = Tracker(fps_hint=FPS, **RECOMMENDED)  # the same without the correction
    for i in range(frames):
        plain.update(i / FPS, person(truth, [0, 1], runtime).world[None], [Origin(cameras=(0, 1))])
    for i in range(frames, frames + int(2 * FPS)):
        served = plain.update(
            i / FPS, person(truth, [1], runtime).world[None], [Origin(cameras=(1,))]
        )
    assert np.linalg.norm(np.array([served[0].x, served[0].y]) - truth) > 0.8 * error


def test_an_offset_fades_when_not_refreshed_and_unknown_tracks_are_left_alone():
    runtime = BiasedViews()
    bias, tracker = ViewBias(time_constant_s=3.0), Tracker(fps_hint=FPS, **RECOMMENDED)
    truth = np.array([2.0, 2.0])
    for i in range(int(3 * FPS)):
        tracks = step(bias, tracker, i / FPS, [person(truth, [0, 1], runtime)], runtime)
    track_id = tracks[0].id
    now = bias.offset(track_id, 0, 3.0, runtime, truth)
    later = bias.offset(track_id, 0, 3.0 + 20.0, runtime, truth)
    assert now is not None and later is not None
    assert np.linalg.norm(now - BIAS[0]) < 0.2 * np.linalg.norm(BIAS[0])
    assert np.linalg.norm(later) < 0.1 * np.linalg.norm(now)
    assert bias.offset(track_id + 1, 0, 3.0, runtime, truth) is None
    # a lone view far from every track (another person) is not corrected
    stranger = person(np.array([6.0, 6.0]), [0], runtime)
    np.testing.assert_allclose(
        bias.correct(3.0, [stranger], stranger.world[None], runtime)[0], stranger.world
    )


def test_the_pipeline_serves_the_corrected_position():
    """The daemon's pipeline runs the same correction: after 3 s of two views, 1 s of camera 0
    alone keeps the served person near the truth instead of drifting to the lone view's."""
    from service.pipeline.hub import Hub
    from service.pipeline.live import Pipeline

    runtime = BiasedViews()
    truth = np.array([2.5, 3.5])
    both, alone = int(3 * FPS), int(1 * FPS)

    def nobody(frame_set: FrameSet) -> list[Detections]:
        return [Detections.empty()] * 2

    def associate(detections, model, max_error_px=0.0, anchors=()):
        seq = frame_set_seq[0]
        return [person(truth, [0, 1] if seq < both else [0], runtime)]

    frame_set_seq = [0]
    tracker = Tracker(fps_hint=FPS, **RECOMMENDED)
    pipeline = Pipeline(
        NoRig(), FunctionStage(nobody), Hub(), num_cameras=2, runtime=runtime, tracker=tracker,
        associate=associate, shift_threaded=False,
    )  # fmt: skip
    try:
        for i in range(both + alone):
            frame_set_seq[0] = i
            people = pipeline.process(frames_at(i, 50 + i / FPS, (True, True))).people
    finally:
        pipeline.stop()
    assert len(people) == 1
    served = np.array([people[0]["x"], people[0]["y"]])
    assert np.linalg.norm(served - truth) < 0.4 * np.linalg.norm(BIAS[0])
