"""Metric definitions against hand-computed cases."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from common.errors import MomlocError
from models.data.metrics import (
    METRIC_KEYS,
    format_table,
    frame_step,
    localization_metrics,
    relative_errors,
)


def _case() -> tuple[np.ndarray, ...]:
    # Errors along x only: 0.1, 0.25, 0.35, 0.45, 0.6 (rows deliberately out of frame order).
    truth = np.zeros((5, 2))
    pred = np.array([[0.25, 0], [0.1, 0], [0.45, 0], [0.35, 0], [0.0, 0.6]])
    frame = np.array([1, 0, 1, 0, 7])
    track = np.array([0, 0, 1, 1, 2])
    return pred, truth, frame, track


def test_keys_are_exactly_the_contract() -> None:
    m = localization_metrics(*_case())
    assert tuple(m) == METRIC_KEYS
    assert set(m) == {
        "n",
        "mean",
        "median",
        "std",
        "ate",
        "rpe",
        "acc@0.2",
        "acc@0.3",
        "acc@0.4",
        "acc@0.5",
    }
    json.dumps(m)  # plain Python numbers


def test_error_statistics_hand_computed() -> None:
    m = localization_metrics(*_case())
    errors = [0.1, 0.25, 0.35, 0.45, 0.6]
    assert m["n"] == 5
    assert m["mean"] == pytest.approx(1.75 / 5)
    assert m["median"] == pytest.approx(0.35)
    var = sum((e - 0.35) ** 2 for e in errors) / 5  # population std
    assert m["std"] == pytest.approx(math.sqrt(var))
    # ATE: RMSE over every trajectory point.
    assert m["ate"] == pytest.approx(math.sqrt(sum(e * e for e in errors) / 5))


def test_accuracy_thresholds_are_strict_percentages() -> None:
    m = localization_metrics(*_case())
    assert m["acc@0.2"] == pytest.approx(20.0)  # 0.1
    assert m["acc@0.3"] == pytest.approx(40.0)  # 0.1, 0.25
    assert m["acc@0.4"] == pytest.approx(60.0)
    assert m["acc@0.5"] == pytest.approx(80.0)
    exact = localization_metrics(
        np.array([[0.3, 0.0]]), np.zeros((1, 2)), np.zeros(1, int), np.zeros(1, int)
    )
    assert exact["acc@0.3"] == 0.0  # "less than", not "at most"
    assert exact["acc@0.4"] == 100.0


def test_rpe_pairs_consecutive_frames_within_tracks() -> None:
    # Track 0 (sorted by frame): frame0 err +0.1, frame1 err +0.25 -> relative error 0.15.
    # Track 1: frame0 err +0.35, frame1 err +0.45 -> 0.10. Track 2 has one row: no pair.
    m = localization_metrics(*_case())
    assert m["rpe"] == pytest.approx(math.sqrt((0.15**2 + 0.10**2) / 2))


def test_rpe_of_a_constant_offset_is_zero_and_ate_is_the_offset() -> None:
    truth = np.stack([np.linspace(0, 3, 10), np.linspace(1, 2, 10)], axis=1)
    pred = truth + np.array([0.3, -0.4])
    m = localization_metrics(pred, truth, np.arange(10), np.zeros(10, int))
    assert m["rpe"] == pytest.approx(0.0, abs=1e-12)
    assert m["ate"] == pytest.approx(0.5)
    assert m["mean"] == pytest.approx(0.5)
    assert m["std"] == pytest.approx(0.0, abs=1e-12)


def test_rpe_skips_gaps_and_uses_the_data_frame_step() -> None:
    truth = np.zeros((4, 2))
    pred = np.array([[0.0, 0], [0.2, 0], [5.0, 0], [5.0, 0.3]])
    frame = np.array([0, 2, 10, 12])  # step 2; the 2 -> 10 gap is an occlusion
    track = np.zeros(4, int)
    assert frame_step(frame, track) == 2
    rel = relative_errors(pred, truth, frame, track)
    np.testing.assert_allclose(sorted(rel), [0.2, 0.3])
    m = localization_metrics(pred, truth, frame, track)
    assert m["rpe"] == pytest.approx(math.sqrt((0.04 + 0.09) / 2))
    # An explicit delta of 1 finds no pair.
    assert math.isnan(localization_metrics(pred, truth, frame, track, delta=1)["rpe"])


def test_rpe_does_not_pair_rows_of_different_tracks() -> None:
    truth = np.zeros((2, 2))
    pred = np.array([[0.0, 0.0], [1.0, 0.0]])
    m = localization_metrics(pred, truth, np.array([0, 1]), np.array([0, 1]))
    assert math.isnan(m["rpe"])
    assert "n/a" in format_table(m)


def test_three_dimensional_truth_uses_floor_coordinates() -> None:
    truth = np.array([[1.0, 2.0, 0.9]])
    m = localization_metrics(np.array([[1.0, 2.1]]), truth, np.zeros(1, int), np.zeros(1, int))
    assert m["mean"] == pytest.approx(0.1)


def test_bad_input_raises_one_line_error() -> None:
    with pytest.raises(MomlocError, match="NaN"):
        localization_metrics(
            np.array([[np.nan, 0]]), np.zeros((1, 2)), np.zeros(1, int), np.zeros(1, int)
        )
    with pytest.raises(MomlocError, match="does not match"):
        localization_metrics(np.zeros((2, 2)), np.zeros((3, 2)), np.array([0, 1]), np.array([0, 0]))


def test_table_lists_every_metric() -> None:
    text = format_table(localization_metrics(*_case()))
    assert "Acc@0.3 m" in text and "40.00 %" in text and "ATE" in text
