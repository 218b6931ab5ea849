"""The MOTA breakdown's attribution rules (bench/serving/stream_breakdown.py) on hand-made
frames."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bench.serving.stream_breakdown import FALSE, box_labels, measurement_cause


def test_boxes_are_labelled_by_person_or_false():
    person = np.array([[10, 20, 50, 120], [200, 30, 240, 130]], dtype=np.float32)  # camera 0, 1
    other = np.array([[60, 20, 90, 100], [np.nan] * 4], dtype=np.float32)
    obs = SimpleNamespace(boxes=np.stack([person, other]), track=np.array([4, 7]))
    fused = SimpleNamespace(cameras=[0, 1], boxes=person)
    assert box_labels(fused, obs) == [4, 4]
    wrong = SimpleNamespace(cameras=[0, 1], boxes=np.stack([other[0], person[1]]))
    assert box_labels(wrong, obs) == [7, 4]
    ghost = SimpleNamespace(cameras=[1], boxes=np.array([[np.nan] * 4, [1, 2, 3, 4]], np.float32))
    assert box_labels(ghost, obs) == [FALSE]


def test_measurement_causes():
    truth = {4: np.array([1.0, 1.0])}
    assert measurement_cause([4, FALSE], np.array([1.0, 1.0]), truth) == "mis-association"
    assert measurement_cause([FALSE], np.array([1.0, 1.0]), truth) == "ghost"
    assert measurement_cause([4], np.array([1.2, 1.0]), truth) == "filter off"
    assert measurement_cause([4], np.array([2.0, 1.0]), truth) == "single-view range"
    assert measurement_cause([4, 4], np.array([2.0, 1.0]), truth) == "multi-view error"
