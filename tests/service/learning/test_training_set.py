"""The rows a self-improvement run trains on: the marks as recorded, labels by their certainty."""

from __future__ import annotations

import numpy as np
import pytest

from models.data.dataset import MomDataset
from service.learning.training_set import aligned, label_weights, training_set
from tests.models.test_floor_prior import _marks
from tests.models.test_joint_floor import SIZES, _bent, _moments
from tests.service.learning.test_gate import labels_batch, marks_dataset


def test_marks_stay_and_labels_join_as_rows_of_their_own_tracks() -> None:
    marks, labels = marks_dataset(), labels_batch(200)
    rows = training_set(marks, labels)
    assert rows.n == marks.n + labels.n  # std 0.05 m: every label enters
    np.testing.assert_array_equal(rows.world[: marks.n], marks.world)
    assert set(rows.track[marks.n :]).isdisjoint(set(marks.track))
    assert rows.frame[marks.n :].min() > marks.frame.max()
    np.testing.assert_allclose(rows.world[marks.n :], labels.world)


def test_uncertain_labels_count_less() -> None:
    labels = labels_batch(2000)
    labels.covariance[1000:] *= 4.0  # std 0.1 m: a quarter of the weight
    weights = label_weights(labels)
    assert weights[:1000] == pytest.approx(1.0) and weights[1000:] == pytest.approx(0.25)
    rows = training_set(marks_dataset(), labels, seed=1)
    kept = rows.n - marks_dataset().n
    assert 1000 + 0.2 * 1000 < kept < 1000 + 0.3 * 1000


def test_labels_of_another_camera_count_are_refused() -> None:
    labels = labels_batch(10)
    labels.boxes = np.concatenate([labels.boxes, labels.boxes[:, :1]], axis=1)
    with pytest.raises(ValueError, match="3 cameras"):
        training_set(marks_dataset(), labels)


def test_label_positions_are_refitted_jointly_before_training() -> None:
    marks_world, marks_boxes = _marks(grid=2)
    marks = MomDataset(
        world=marks_world.astype(np.float32),
        boxes=marks_boxes.astype(np.float32),
        frame=np.arange(len(marks_world)),
        track=np.zeros(len(marks_world), np.int64),
        image_size=SIZES.astype(np.int64),
    )
    truth, boxes = _moments(300, seed=4)
    labels = labels_batch(300)
    labels.world, labels.boxes = _bent(truth).astype(np.float32), boxes.astype(np.float32)
    labels.covariance *= 16.0  # std 0.2 m as served: a sixteenth of the weight as they are
    taught, placed, note = aligned(marks, labels)
    assert "fitted jointly on" in note and placed.sum() >= 290  # a few boxes cut at a border
    served_off = np.linalg.norm(labels.world - truth, axis=1).mean()
    assert np.linalg.norm(taught.world - truth, axis=1).mean() < 0.3 * served_off
    np.testing.assert_array_equal(taught.boxes, labels.boxes)
    # The served covariance does not describe a position the cameras' maps re-triangulated:
    # those labels enter whole, the rest as sure as the serving model said.
    rows = training_set(marks, taught, placed=placed)
    assert placed.sum() <= rows.n - marks.n <= labels.n
    assert training_set(marks, taught).n - marks.n < 0.2 * labels.n
    labels.boxes[:, 1] = np.nan  # one camera: nothing to agree on, the positions stay
    kept, placed, why = aligned(marks, labels)
    assert why.startswith("positions as served") and kept is labels and not placed.any()
