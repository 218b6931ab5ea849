"""The CMC bench's per-frame scorer (bench/real/cmc_score.py) on a hand-made frame whose
counts and attribution are worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from bench.real.cmc_score import FrameEval, score_frames


def test_hand_made_frames() -> None:
    # frame 1: people 1 (2 cameras), 2 (3 cameras), 3 (no box anywhere), 4 (1 camera)
    #   est a at person 1, 0.1 m off (tp); est b at person 1 too (duplicate); est c from boxes
    #   of nobody; est d from boxes of persons 2 and 4 between them (mixed, > gate from both);
    #   est e from person 4's box, 0.8 m off (off); persons 2, 3, 4 missed (2, 4 with a box)
    # frame 2: person 1 alone, est at 0.3 m (tp)
    one = FrameEval(
        truth_ids=np.array([1, 2, 3, 4]),
        truth_xy=np.array([[0.0, 0.0], [3.0, 0.0], [6.0, 0.0], [3.0, 3.0]]),
        truth_views=np.array([2, 3, 0, 1]),
        est_xy=np.array([[0.1, 0.0], [0.3, 0.3], [9.0, 9.0], [3.0, 1.5], [3.8, 3.0]]),
        est_people=[{1}, {1}, set(), {2, 4}, {4}],
        est_views=[2, 1, 1, 2, 1],
    )
    two = FrameEval(
        np.array([1]), np.array([[1.0, 1.0]]), np.array([4]), np.array([[1.3, 1.0]]), [{1}], [4]
    )
    r = score_frames([one, two])
    assert (r["gt"], r["tp"], r["fp"], r["fn"]) == (5, 2, 4, 3)
    assert r["moda"] == pytest.approx(100 * (1 - 7 / 5))
    assert r["precision"] == pytest.approx(100 * 2 / 6) and r["recall"] == pytest.approx(40.0)
    assert r["matched_mean_m"] == pytest.approx(0.2)
    assert r["modp"] == pytest.approx(100 * ((1 - 0.1 / 0.5) + (1 - 0.3 / 0.5)) / 2)
    assert r["fp_breakdown"] == {"nobody": 1, "mixed": 1, "duplicate": 1, "off": 1}
    assert r["fn_breakdown"] == {"with_box": 2, "without_box": 1}
    assert r["people_by_cameras"] == {"0": 0.2, "1": 0.2, "2": 0.2, "3": 0.2, "4": 0.2}
    assert r["recall_by_cameras"]["2"] == 100.0 and r["recall_by_cameras"]["3"] == 0.0
    assert r["estimates_by_cameras"] == {"0": 0, "1": 3, "2": 2, "3": 0, "4": 1}
    assert r["fp_by_cameras"] == {"0": 0, "1": 3, "2": 1, "3": 0, "4": 0}


def test_anchor_without_attribution_has_no_fp_breakdown() -> None:
    frame = FrameEval(np.array([1]), np.array([[0.0, 0.0]]), np.array([1]), np.array([[2.0, 0.0]]))
    r = score_frames([frame])
    assert (r["tp"], r["fp"], r["fn"]) == (0, 1, 1) and "fp_breakdown" not in r
