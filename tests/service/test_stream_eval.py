"""What the offline stream run hands the association: each camera's shuffled detector report,
detected every frame set or on the daemon's schedule with carried boxes."""

from __future__ import annotations

import numpy as np

from models.detector.base import Detections
from models.simulate import Scene
from models.simulate.observation import FrameObservation
from service.offline.stream_eval import ScheduledBoxes, frame_detections, scene_config


def _observation_with_false_boxes() -> FrameObservation:
    scene = Scene(scene_config("indoor-2cam", 3, "nanodet"), seed=4)
    for i in range(400):
        obs = scene.observe(i)
        if np.isfinite(obs.false_boxes).all(-1).any() and np.isfinite(obs.boxes).all(-1).any():
            return obs
    raise AssertionError("no frame with both people and false boxes")


def test_keypoints_ride_with_their_boxes_and_false_boxes_have_none() -> None:
    obs = _observation_with_false_boxes()
    for k, found in enumerate(frame_detections(obs, np.random.default_rng(0))):
        people = obs.boxes[:, k][np.isfinite(obs.boxes[:, k]).all(-1)]
        false = obs.false_boxes[k][np.isfinite(obs.false_boxes[k]).all(-1)]
        assert len(found) == len(people) + len(false)
        assert found.keypoints is not None
        for box, points in zip(found.boxes, found.keypoints, strict=True):
            person = np.flatnonzero(np.all(np.isclose(obs.boxes[:, k], box), axis=1))
            if len(person):  # a person's box carries that person's keypoints
                expected = obs.keypoints[person[0], k].astype(np.float32)
                np.testing.assert_array_equal(points, expected)
            else:  # a false box: a pose estimator finds no body in it
                assert np.isnan(points).all()
        assert not np.isnan(found.keypoints).all() or not len(people)


def test_scheduled_boxes_arrive_late_and_are_carried_in_between() -> None:
    """Every 3rd frame set detected, 2 frame sets late: nothing is served before the first
    result arrives, a person walking right at constant speed is served on every frame set after
    it, and the carried box follows the walk (the filter learns the speed from two detections)."""
    fps, speed = 30.0, 60.0  # px per second

    def found(i: int) -> list[Detections]:
        x = 100.0 + speed * i / fps
        box = np.array([[x, 100.0, x + 50.0, 250.0]], np.float32)
        return [Detections(box, np.ones(1, np.float32))]

    schedule = ScheduledBoxes(every=3, delay=2)
    served = [schedule(i, i / fps, found(i), fps)[0] for i in range(30)]
    assert len(served[0]) == len(served[1]) == 0  # frame 0's result arrives at frame 2
    assert all(len(d) == 1 for d in served[2:])
    late = [float(served[i].boxes[0, 0] - found(i)[0].boxes[0, 0]) for i in range(20, 30)]
    assert max(abs(e) for e in late) < 3.0  # px: carried with the walk, not held in place
    held = found(0)[0].boxes[0, 0]
    assert served[29].boxes[0, 0] > held + 50.0
