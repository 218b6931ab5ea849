"""Evaluation core: compatibility checks, batching, unseen rows (with a geometric localizer)."""

from __future__ import annotations

import numpy as np
import pytest

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.geometry import calibrated_baseline as baseline
from models.mom.evaluate import check_compatible, evaluate, predict


class FootLocalizer:
    """A calibrated localizer with the MomRuntime shape: foot-point back-projection."""

    observation = "bbox"

    def __init__(self, projections: np.ndarray) -> None:
        self.projections = projections
        self.num_cameras = len(projections)
        self.calls = 0

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        self.calls += 1
        return baseline.localize(boxes, self.projections, method="foot")


def _camera(eye: np.ndarray) -> np.ndarray:
    forward = np.array([2.0, 2.0, 0.0]) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0, 1])
    right /= np.linalg.norm(right)
    rot = np.stack([right, np.cross(forward, right), forward])
    k = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    return k @ np.concatenate([rot, (-rot @ eye)[:, None]], axis=1)


CAMERAS = np.stack([_camera(np.array([-2.0, -2.0, 2.5])), _camera(np.array([6.0, -2.0, 2.5]))])


def _dataset(n: int = 40) -> MomDataset:
    t = np.arange(n)
    world = np.stack([1 + 0.05 * t, 2 + 0.5 * np.sin(t / 5)], axis=1)
    foot = np.concatenate([world, np.zeros((n, 1))], axis=1)
    views = []
    for p in CAMERAS:
        uv = baseline.project(p, foot)
        views.append(np.concatenate([uv - [15.0, 150.0], uv + np.array([15.0, 0.0])], axis=1))
    boxes = np.stack(views, axis=1)
    boxes[5] = np.nan  # nobody sees row 5
    return MomDataset(
        world=world,
        boxes=boxes,
        frame=t % 20,
        track=t // 20,
        image_size=np.array([[640, 480], [640, 480]]),
    )


def test_exact_localizer_scores_perfectly_and_skips_unseen_rows() -> None:
    data = _dataset()
    result = evaluate(FootLocalizer(CAMERAS), data)
    assert result.skipped == 1 and 5 not in result.rows
    assert result.metrics["n"] == data.n - 1
    assert result.metrics["mean"] < 1e-6 and result.metrics["acc@0.2"] == 100.0


def test_a_shifted_camera_shows_up_in_the_metrics() -> None:
    data = _dataset()
    moved = CAMERAS.copy()
    moved[0] = np.array([[1, 0, 25.0], [0, 1, 0], [0, 0, 1]]) @ moved[0]  # 25 px bump
    metrics = evaluate(FootLocalizer(moved), data).metrics
    assert 0.005 < metrics["mean"] < 1.0
    assert metrics["rpe"] < metrics["ate"]  # a constant-ish bias moves little frame to frame


def test_predictions_do_not_depend_on_batching() -> None:
    data = _dataset()
    runtime = FootLocalizer(CAMERAS)
    whole = predict(runtime, data)
    runtime.calls = 0
    pieces = predict(runtime, data, batch=7)
    assert runtime.calls == 6
    np.testing.assert_array_equal(whole, pieces)


def test_camera_count_mismatch_is_refused() -> None:
    with pytest.raises(MomlocError, match="2 cameras but the model was trained for 3"):
        check_compatible(FootLocalizer(np.concatenate([CAMERAS, CAMERAS[:1]])), _dataset())


def test_keypoint_model_needs_keypoints() -> None:
    runtime = FootLocalizer(CAMERAS)
    runtime.observation = "keypoints"
    with pytest.raises(MomlocError, match="no 'keypoints'"):
        check_compatible(runtime, _dataset())
