"""The detector benchmark's metrics on hand-made cases whose answers are known by construction."""

from __future__ import annotations

import numpy as np
import pytest

from bench.detector.data import simulated_truth
from bench.detector.metrics import Truth, evaluate, iou_matrix, match_frame


def test_iou_matrix_known_values() -> None:
    a = np.array([[0, 0, 10, 10]])
    b = np.array([[0, 0, 10, 10], [5, 0, 15, 10], [20, 20, 30, 30], [0, 0, 10, 5]])
    np.testing.assert_allclose(iou_matrix(a, b), [[1.0, 50 / 150, 0.0, 0.5]])
    assert iou_matrix(np.zeros((0, 4)), b).shape == (0, 4)


def test_greedy_matching_by_score_and_best_overlap() -> None:
    truth = Truth.of([[0, 0, 20, 100], [30, 0, 50, 100]])
    dets = np.array([[0, 0, 20, 100], [1, 0, 21, 100], [28, 0, 48, 100]])
    # The lower-scored exact box loses the first person to the higher-scored near copy.
    match = match_frame(truth, dets, np.array([0.6, 0.9, 0.8]), 0.5)
    assert match.matched.tolist() == [1, 2]
    assert match.status.tolist() == ["fp", "tp", "tp"]


def test_iou_threshold_decides_hit_or_false_positive_and_miss() -> None:
    truth = Truth.of([[0, 0, 20, 100]])
    wide = np.array([[0, 0, 45, 100]])  # IoU 20/45 = 0.44
    strict = match_frame(truth, wide, np.array([0.9]), 0.5)
    assert not strict.found[0] and strict.status.tolist() == ["fp"]
    loose = match_frame(truth, wide, np.array([0.9]), 0.3)
    assert loose.found[0] and loose.status.tolist() == ["tp"]


def test_ignored_people_count_neither_way() -> None:
    truth = Truth.of([[0, 0, 20, 100], [100, 0, 110, 20]], ignore=[False, True])
    dets = np.array([[100, 0, 110, 20], [101, 2, 108, 12]])  # on the ignored one; inside it
    ev = evaluate([(truth, dets, np.array([0.9, 0.8]))], 0.3, 0.5)
    assert ev.false_positives == 0 and ev.true_positives == 0
    assert ev.heights.tolist() == [100.0]  # the ignored person is not in recall
    assert ev.recall() == (0.0, 1)


def test_recall_by_height_bins_and_bin_edges() -> None:
    truth = Truth.of([[0, 0, 10, 50], [20, 0, 40, 100], [50, 0, 70, 150], [80, 0, 120, 250]])
    dets = np.array([[20, 0, 40, 100], [80, 0, 120, 250]])  # finds the 100 px and 250 px people
    ev = evaluate([(truth, dets, np.array([0.9, 0.9]))], 0.4, 0.5)
    assert ev.recall(0, 100) == (0.0, 1)  # 50 px only: 100 belongs to the next bin
    assert ev.recall(100, 200) == (0.5, 2)
    assert ev.recall(200, np.inf) == (1.0, 1)
    assert ev.recall(80, 300) == (2 / 3, 3)
    recall, counts = ev.recall_curve([0, 100, 200, 300])
    assert counts.tolist() == [1, 2, 1] and recall.tolist() == [0.0, 0.5, 1.0]


def test_score_threshold_drops_detections_before_matching() -> None:
    truth = Truth.of([[0, 0, 20, 100]])
    nothing = (Truth.of([]), np.zeros((0, 4)), np.zeros(0))
    frames = [(truth, np.array([[0, 0, 20, 100]]), np.array([0.35])), nothing]
    assert evaluate(frames, 0.3, 0.5).recall()[0] == 1.0
    high = evaluate(frames, 0.4, 0.5)
    assert high.recall()[0] == 0.0 and high.frames == 2 and np.isnan(high.precision)


def test_precision_and_false_positives_per_frame() -> None:
    truth = Truth.of([[0, 0, 20, 100]])
    frames = [
        (truth, np.array([[0, 0, 20, 100], [300, 0, 320, 100]]), np.array([0.9, 0.9])),
        (Truth.of([]), np.array([[10, 10, 30, 90]]), np.array([0.5])),
    ]
    ev = evaluate(frames, 0.4, 0.5)
    assert ev.precision == pytest.approx(1 / 3)
    assert ev.fp_per_frame == pytest.approx(1.0)


def test_edge_error_sign_and_fully_visible_people_only() -> None:
    truth = Truth.of(
        [[0, 100, 20, 200], [50, 100, 70, 200], [100, 100, 120, 200]],
        occluded=[False, False, True],
    )
    dets = np.array(
        [
            [0, 95, 20, 210],  # top 5 px above the head, bottom 10 px below the foot
            [50, 104, 70, 196],  # top 4 px into the head, bottom 4 px above the foot
            [100, 150, 120, 260],  # occluded person: its errors must not count
        ]
    )
    ev = evaluate([(truth, dets, np.ones(3))], 0.4, 0.3)
    np.testing.assert_allclose(ev.bottom, [0.10, -0.04, 0.60])
    np.testing.assert_allclose(ev.top, [-0.05, 0.04, 0.50])
    bottom = ev.edge_stats("bottom")
    assert bottom["n"] == 2
    assert bottom["median_abs"] == pytest.approx(0.07)
    assert bottom["bias"] == pytest.approx(0.03)
    assert ev.edge_stats("top", 0, 50)["n"] == 0


def test_simulated_truth_flags_occlusion_truncation_and_ignore() -> None:
    boxes = np.array(
        [
            [100, 100, 140, 300],  # far, half behind the near one
            [120, 100, 180, 320],  # near
            [620, 100, 700, 300],  # 25 % inside the 640 px frame
            [np.nan] * 4,  # unseen
        ]
    )
    truth = simulated_truth(boxes, np.array([5.0, 2.0, 3.0, 1.0]), (640, 480))
    assert truth.boxes.shape == (3, 4)
    assert truth.occluded.tolist() == [True, False, False]
    assert truth.truncated.tolist() == [False, False, True]
    assert truth.ignore.tolist() == [False, False, True]  # less than 30 % visible
    assert truth.boxes[2, 2] == 640
