"""Fixed-lag smoothing for offline tracking (service.tracking.smoother): no lag, less shake, every
snapshot once and in order."""

from __future__ import annotations

import numpy as np
import pytest

from service.snapshot import Snapshot
from service.tracking.smoother import FixedLagSmoother
from tests.people import person

FPS = 15.0


def stream(positions: np.ndarray, track_id: int = 7) -> list[tuple[int, Snapshot]]:
    return [
        (f, Snapshot.build(f + 1, f / FPS, [{"id": track_id, "x": x, "y": y, "vx": 0.0,
                                              "vy": 0.0, "confidence": 1.0, "cameras": [0]}]))
        for f, (x, y) in enumerate(positions)
    ]  # fmt: skip


def smooth(frames: list[tuple[int, Snapshot]], half_window_s: float = 0.5):
    smoother = FixedLagSmoother(half_window_s)
    out = []
    for frame, snapshot in frames:
        out += smoother.push(frame, snapshot)
    return out + smoother.flush()


def xy(out: list[tuple[int, Snapshot]]) -> np.ndarray:
    return np.array([[s.people[0]["x"], s.people[0]["y"]] for _, s in out])


def test_a_steady_walk_passes_without_lag():
    """A walk at 1.2 m/s: every smoothed position is where the person is at that snapshot's
    time (a causal smoother would trail by its window), and the velocity is the walk's."""
    t = np.arange(60) / FPS
    walk = np.stack([1.0 + 1.2 * t, 2.0 - 0.5 * t], axis=1)
    out = smooth(stream(walk))
    np.testing.assert_allclose(xy(out), walk, atol=2e-4)
    inner = out[10:-10]
    assert all(s.people[0]["vx"] == pytest.approx(1.2, abs=1e-3) for _, s in inner)
    assert all(s.people[0]["vy"] == pytest.approx(-0.5, abs=1e-3) for _, s in inner)


def test_a_standing_persons_shake_shrinks_and_a_jump_is_spread():
    rng = np.random.default_rng(0)
    still = np.array([3.0, 1.0]) + rng.normal(0.0, 0.03, (90, 2))
    still[45:] += [0.3, 0.0]  # a second camera arrives and moves the fix by 0.3 m
    served = xy(smooth(stream(still)))
    raw_steps = np.linalg.norm(np.diff(still, axis=0), axis=1)
    steps = np.linalg.norm(np.diff(served, axis=0), axis=1)
    assert np.sqrt(np.mean(steps**2)) < 0.5 * np.sqrt(np.mean(raw_steps**2))
    assert steps.max() < 0.5 * raw_steps.max()


def test_every_snapshot_once_in_order_and_a_short_track_as_tracked():
    frames = stream(np.tile([[1.0, 1.0]], (40, 1)))
    # a second id seen in two frames only: too few samples to fit, left as tracked
    frames[20][1].people.append(person(9, 5.0, 5.0, vx=0.3))
    frames[21][1].people.append(person(9, 5.2, 5.0, vx=0.3))
    smoother = FixedLagSmoother(0.5)
    released = [[f for f, _ in smoother.push(f, s)] for f, s in frames]
    assert released[0] == [] and released[7] == [] and released[8] == [0]  # 0.53 s later
    out = [f for batch in released for f in batch] + [f for f, _ in smoother.flush()]
    assert out == list(range(40))
    out = smooth(frames)
    lone = [p for _, s in out for p in s.people if p["id"] == 9]
    assert [(p["x"], p["vx"]) for p in lone] == [(5.0, 0.3), (5.2, 0.3)]
    assert [s.seq for _, s in out] == [s.seq for _, s in frames]


def test_a_non_positive_window_is_refused():
    with pytest.raises(ValueError, match="half_window_s"):
        FixedLagSmoother(0.0)
