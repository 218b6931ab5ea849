"""Served-accuracy metrics on hand-made streams whose right answers are known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.errors import MomlocError
from models.data.stream_metrics import StreamFrame, StreamScorer, score_stream

FPS = 15.0


def standing(n: int = 30, xy=(2.0, 3.0)) -> np.ndarray:
    return np.tile(np.asarray(xy, float), (n, 1))


def walking(n: int = 150, speed: float = 1.0, delay_s: float = 0.0) -> np.ndarray:
    """A person walking along x at ``speed`` m/s, sampled at FPS, ``delay_s`` behind."""
    t = np.arange(n) / FPS - delay_s
    return np.stack([1.0 + speed * t, np.full(n, 2.0)], axis=1)


def stream(truth: dict[int, np.ndarray], served: dict[int, np.ndarray], views=None):
    """Frames from per-id trajectories ([F, 2], NaN rows: absent that frame)."""
    n = max(len(a) for a in (*truth.values(), *served.values()))
    frames = []
    for i in range(n):
        t_ids = [o for o, a in truth.items() if i < len(a) and np.isfinite(a[i]).all()]
        s_ids = [h for h, a in served.items() if i < len(a) and np.isfinite(a[i]).all()]
        frames.append(
            StreamFrame(
                t=i / FPS,
                truth_ids=np.array(t_ids, dtype=int),
                truth_xy=np.array([truth[o][i] for o in t_ids]).reshape(-1, 2),
                served_ids=np.array(s_ids, dtype=int),
                served_xy=np.array([served[h][i] for h in s_ids]).reshape(-1, 2),
                views=None if views is None else np.array([views[o][i] for o in t_ids], int),
            )
        )
    return frames


def test_perfect_stream():
    truth = {0: walking(), 1: standing(150)}
    m = score_stream(stream(truth, {10: truth[0], 11: truth[1]}))
    assert (m["tp"], m["fp"], m["fn"], m["id_switches"]) == (300, 0, 0, 0)
    assert m["precision"] == m["recall"] == m["mota"] == 100.0
    assert m["mean"] == 0.0 and m["acc@0.3"] == 100.0
    assert m["jitter_m"] == 0.0 and m["jitter_n"] == 149
    assert abs(m["lag_s"]) < 1e-6


def test_id_change_counts_once():
    """The person's served id changes once (a new track): one switch, not one per frame."""
    truth = {0: walking(60)}
    first, second = truth[0].copy(), truth[0].copy()
    first[30:], second[:30] = np.nan, np.nan
    m = score_stream(stream(truth, {1: first, 2: second}))
    assert m["id_switches"] == 1
    assert m["mota"] == pytest.approx(100.0 * (1 - 1 / 60))
    assert m["recall"] == 100.0


def test_swap_of_two_people_is_two_switches():
    a, b = walking(60), walking(60) + np.array([0.0, 1.5])
    one, two = a.copy(), b.copy()
    one[30:], two[30:] = b[30:], a[30:]
    m = score_stream(stream({0: a, 1: b}, {1: one, 2: two}))
    assert m["id_switches"] == 2
    assert m["tp"] == 120 and m["fp"] == 0


def test_ghost_is_a_false_positive():
    truth = {0: standing(40)}
    m = score_stream(stream(truth, {1: truth[0], 9: standing(40, (8.0, 8.0))}))
    assert (m["tp"], m["fp"], m["fn"]) == (40, 40, 0)
    assert m["precision"] == 50.0 and m["recall"] == 100.0
    assert m["mota"] == 0.0


def test_missed_frame_lowers_recall_without_switch():
    truth = {0: walking(50)}
    served = truth[0].copy()
    served[20] = np.nan
    m = score_stream(stream(truth, {1: served}))
    assert m["fn"] == 1 and m["id_switches"] == 0
    assert m["recall"] == pytest.approx(100.0 * 49 / 50)
    assert m["precision"] == 100.0


def test_gate_decides_a_far_position():
    truth = {0: standing(20)}
    served = {1: standing(20, (2.7, 3.0))}  # 0.7 m off
    strict, lenient = (score_stream(stream(truth, served), gate) for gate in (0.5, 1.0))
    assert (strict["tp"], strict["fp"], strict["fn"]) == (0, 20, 20)
    assert math.isnan(strict["mean"])
    assert lenient["tp"] == 20 and lenient["mean"] == pytest.approx(0.7)
    assert lenient["acc@0.3"] == 0.0


def test_constant_offset_is_bias_not_jitter():
    truth = {0: standing(60)}
    m = score_stream(stream(truth, {1: truth[0] + [0.2, 0.1]}))
    assert m["jitter_m"] == pytest.approx(0.0, abs=1e-12)
    assert m["mean"] == pytest.approx(math.hypot(0.2, 0.1))


def test_jitter_of_white_noise():
    """i.i.d. noise of std s per axis: the frame-to-frame change has RMS 2 s."""
    truth = {0: standing(4000)}
    rng = np.random.default_rng(0)
    m = score_stream(stream(truth, {1: truth[0] + rng.normal(0, 0.01, (4000, 2))}))
    assert m["jitter_m"] == pytest.approx(0.02, rel=0.05)


def test_walking_person_is_not_standing():
    """Jitter is measured while the truth stands still only: a walk adds nothing."""
    truth = {0: walking(60), 1: standing(60, (5.0, 5.0))}
    served = {1: walking(60) + [0.0, 0.05] * (np.arange(60) % 2)[:, None], 2: truth[1]}
    m = score_stream(stream(truth, served))
    assert m["jitter_m"] == 0.0 and m["jitter_n"] == 59


def test_delayed_stream_gives_its_lag():
    truth = {0: walking(150, speed=1.2)}
    m = score_stream(stream(truth, {1: walking(150, speed=1.2, delay_s=0.2)}))
    assert m["lag_s"] == pytest.approx(0.2, abs=0.003)
    assert m["along_track_lag_s"] == pytest.approx(0.2, abs=1e-6)
    assert m["lag_n"] > 100


def test_lag_on_a_curve_and_a_lead():
    t = np.arange(300) / FPS
    circle = lambda s: np.stack([5 + 2 * np.cos(0.5 * s), 5 + 2 * np.sin(0.5 * s)], 1)  # noqa: E731
    m = score_stream(stream({0: circle(t)}, {1: circle(t - 0.12)}))
    assert m["lag_s"] == pytest.approx(0.12, abs=0.003)
    ahead = score_stream(stream({0: circle(t)}, {1: circle(t + 0.1)}))
    assert ahead["lag_s"] == pytest.approx(-0.1, abs=0.003)


def test_split_by_views():
    truth = {0: standing(20), 1: standing(20, (6.0, 6.0))}
    served = {1: truth[0] + [0.1, 0.0], 2: truth[1] + [0.0, 0.25]}
    views = {0: np.full(20, 2), 1: np.r_[np.full(10, 1), np.full(10, 0)]}
    m = score_stream(stream(truth, served, views))
    split = m["by_views"]
    assert split["2"]["mean"] == pytest.approx(0.1) and split["2"]["gt"] == 20
    assert split["1"]["mean"] == pytest.approx(0.25) and split["1"]["n"] == 10
    assert split["0"]["gt"] == 10 and split["0"]["recall"] == 100.0
    assert split["3+"]["gt"] == 0 and math.isnan(split["3+"]["mean"])


def test_kept_correspondence_is_not_stolen():
    """A neighbour's track passing closer does not take the person's match (no fake switches)."""
    truth = {0: standing(30)}
    own = truth[0] + [0.3, 0.0]
    other = np.full((30, 2), np.nan)
    other[10:20] = truth[0][10:20] + np.array([0.0, 0.1])
    m = score_stream(stream(truth, {1: own, 2: other}))
    assert m["id_switches"] == 0 and m["fp"] == 10


def test_bad_input_is_refused():
    scorer = StreamScorer()
    origin, nobody = np.zeros((1, 2)), np.zeros((0, 2))
    scorer.add(1.0, [0], origin, [], nobody)
    with pytest.raises(MomlocError, match="does not follow"):
        scorer.add(1.0, [0], origin, [], nobody)
    with pytest.raises(MomlocError, match="twice"):
        scorer.add(2.0, [0, 0], np.array([[0.0, 0.0], [1.0, 1.0]]), [], nobody)
    with pytest.raises(MomlocError, match="gate"):
        StreamScorer(gate_m=0.0)


def test_add_returns_the_frames_matches():
    """(truth row, served row) pairs within the gate, for diagnostics (bench/stream_breakdown)."""
    scorer = StreamScorer(0.5)
    truth, served = np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([[3.1, 0.0], [5.0, 5.0]])
    assert scorer.add(0.0, [4, 5], truth, [9, 8], served) == [(1, 0)]
    assert scorer.add(0.1, [4], np.zeros((1, 2)), [], np.zeros((0, 2))) == []
