"""IDF1 (models.data.idf1) on hand-made streams whose answer is counted by hand."""

from __future__ import annotations

import numpy as np
import pytest

from models.data.idf1 import identity_scores
from models.data.stream_metrics import StreamFrame


def frame(
    t: float, truth: dict[int, tuple[float, float]], served: dict[int, tuple[float, float]]
) -> StreamFrame:
    return StreamFrame(
        t,
        np.array(list(truth), np.int64),
        np.array(list(truth.values()), float).reshape(-1, 2),
        np.array(list(served), np.int64),
        np.array(list(served.values()), float).reshape(-1, 2),
    )


def test_one_person_whose_id_changes_halfway() -> None:
    # 4 frames of person 1; served id 10 for two frames, then id 11: the best single id
    # follows them 2 frames, so idtp 2, idfp 2, idfn 2, IDF1 = 4 / 8
    frames = [frame(t, {1: (t, 0)}, {10 if t < 2 else 11: (t + 0.1, 0)}) for t in range(4)]
    result = identity_scores(frames)
    assert (result["idtp"], result["idfp"], result["idfn"]) == (2, 2, 2)
    assert result["idf1"] == pytest.approx(50.0)


def test_ghost_miss_and_gate() -> None:
    # person 1 served well by id 5 in 3 frames; frame 3 also a ghost (id 6); person 2 missed in
    # every frame; frame 2's id-5 position is 0.6 m off (beyond the 0.5 m gate)
    frames = [
        frame(0, {1: (0, 0), 2: (3, 3)}, {5: (0.1, 0)}),
        frame(1, {1: (1, 0), 2: (3, 3)}, {5: (1.1, 0)}),
        frame(2, {1: (2, 0), 2: (3, 3)}, {5: (2.6, 0)}),
        frame(3, {1: (3, 0), 2: (3, 3)}, {5: (3.0, 0), 6: (9, 9)}),
    ]
    result = identity_scores(frames)
    # truth 8, served 5; idtp 3 (frames 0, 1, 3); IDF1 = 6 / 13
    assert (result["idtp"], result["idfp"], result["idfn"]) == (3, 2, 5)
    assert result["idf1"] == pytest.approx(100 * 6 / 13)
    assert result["idp"] == pytest.approx(60.0) and result["idr"] == pytest.approx(37.5)


def test_empty_stream_is_nan() -> None:
    assert np.isnan(identity_scores([])["idf1"])
