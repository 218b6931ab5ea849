"""The stream bound's oracle (bench/serving/stream_bound.py): its filters on hand-made reports, and
the
truth oracle on a scene with a detector that misses nobody."""

from __future__ import annotations

import numpy as np
import pytest

from bench.serving.stream_bound import WINDOW_S, filtered, oracle_scores


def _frames(reports: list[list[float]]) -> list[dict[str, np.ndarray]]:
    """One person (track 3), one report per frame (NaN: no camera reports them)."""
    return [
        {"track": np.array([3]), "reported": np.array([xy], dtype=np.float64)} for xy in reports
    ]


def test_filters_take_the_median_over_the_window_and_keep_gaps():
    fps = 2 / WINDOW_S  # the window holds two frames on each side
    xs = [0.0, 1.0, 10.0, 3.0, np.nan, 5.0]
    centred = _frames([[x, 0.0] for x in xs])
    filtered(centred, fps, "centred")
    got = [float(f["reported"][0, 0]) for f in centred]
    # ±2 frames, reported ones only; the gap stays a gap
    assert got[:4] == [1.0, 2.0, 2.0, 4.0] and np.isnan(got[4]) and got[5] == 4.0
    causal = _frames([[x, 0.0] for x in xs])
    filtered(causal, fps, "causal")
    got = [float(f["reported"][0, 0]) for f in causal]
    assert got[:4] == [0.0, 0.5, 1.0, 3.0] and np.isnan(got[4]) and got[5] == 4.0
    untouched = _frames([[x, 0.0] for x in xs])
    filtered(untouched, fps, "none")
    assert float(untouched[2]["reported"][0, 0]) == 10.0


def test_still_filter_averages_the_reports_since_the_person_stopped():
    fps = 10.0
    xs = [0.0, 1.0, 3.0, np.nan, 5.0, 7.0]
    frames = _frames([[x, 0.0] for x in xs])
    # walks on the first step (0.1 m in 0.1 s), stands from frame 1, walks again at frame 5
    walk = [0.0, 0.1, 0.1, 0.1, 0.1, 0.5]
    for frame, x in zip(frames, walk, strict=True):
        frame["world"] = np.array([[x, 2.0]])
    filtered(frames, fps, "still")
    got = [float(f["reported"][0, 0]) for f in frames]
    # the first frame has no speed yet and the moving frames keep their own report; a gap
    # stays a gap and does not end the stillness
    assert got[:3] == [0.0, 1.0, 2.0] and np.isnan(got[3]) and got[4] == 3.0 and got[5] == 7.0


def test_truth_oracle_is_perfect_when_the_detector_misses_nobody():
    scores = oracle_scores("indoor-2cam", 2, "ideal", 7, 60, 0.5, ("truth", "none", "hold"))
    assert scores["gt"] > 0 and scores["fp"] == 0 and scores["id_switches"] == 0
    # ideal boxes are still cut at image borders and occluded: a few people no camera reports
    assert scores["recall"] > 95.0
    assert scores["mean"] == pytest.approx(0.0, abs=1e-6)
