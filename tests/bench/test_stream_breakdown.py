"""The MOTA breakdown's attribution rules (bench/serving/stream_breakdown.py) on hand-made
frames."""

from __future__ import annotations

import numpy as np

from bench.serving.stream_breakdown import FALSE, box_labels, measurement_cause
from models.simulate.observation import FrameObservation
from service.stages import Association


def _observation(boxes: np.ndarray, track: np.ndarray) -> FrameObservation:
    """A frame with these detected boxes [P, K, 4] of people ``track`` (the rest empty)."""
    none = np.zeros(0)
    return FrameObservation(0, track, none, none, boxes, none, none, none, none, none, none, none)


def _seen(cameras: list[int], boxes: np.ndarray) -> Association:
    index: list[int | None] = [0 if k in cameras else None for k in range(len(boxes))]
    return Association(boxes, cameras, np.zeros(2), 0.0, index)


def test_boxes_are_labelled_by_person_or_false():
    person = np.array([[10, 20, 50, 120], [200, 30, 240, 130]], dtype=np.float32)  # camera 0, 1
    other = np.array([[60, 20, 90, 100], [np.nan] * 4], dtype=np.float32)
    obs = _observation(np.stack([person, other]), np.array([4, 7]))
    fused = _seen([0, 1], person)
    assert box_labels(fused, obs) == [4, 4]
    wrong = _seen([0, 1], np.stack([other[0], person[1]]))
    assert box_labels(wrong, obs) == [7, 4]
    ghost = _seen([1], np.array([[np.nan] * 4, [1, 2, 3, 4]], np.float32))
    assert box_labels(ghost, obs) == [FALSE]


def test_measurement_causes():
    truth = {4: np.array([1.0, 1.0])}
    assert measurement_cause([4, FALSE], np.array([1.0, 1.0]), truth) == "mis-association"
    assert measurement_cause([FALSE], np.array([1.0, 1.0]), truth) == "ghost"
    assert measurement_cause([4], np.array([1.2, 1.0]), truth) == "filter off"
    assert measurement_cause([4], np.array([2.0, 1.0]), truth) == "single-view range"
    assert measurement_cause([4, 4], np.array([2.0, 1.0]), truth) == "multi-view error"
