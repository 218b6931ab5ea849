"""What the offline stream run hands the association: each camera's shuffled detector report."""

from __future__ import annotations

import numpy as np

from models.simulate import Scene
from models.simulate.observation import FrameObservation
from service.offline.stream_eval import frame_detections, scene_config


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
