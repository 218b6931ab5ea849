"""The tracker's measurement covariance scale, learned from its innovations
(:mod:`service.tracking.noise_scale`)."""

from __future__ import annotations

import numpy as np
import pytest

from service.stages import Origin
from service.tracking.noise_scale import CHI2_2_MEDIAN, MAX_SCALE, MIN_SCALE, NoiseScale
from service.tracking.tracker import RECOMMENDED, Tracker


def walk_and_stand(tracker: Tracker, fps: float, seconds: float, true_std: float, given_std: float,
                   seed: int = 0) -> list[float]:  # fmt: skip
    """Two people, one walking a loop and one standing, measured with ``true_std`` noise while
    the localizer claims ``given_std``; returns the scale after each frame set."""
    rng = np.random.default_rng(seed)
    given = np.eye(2) * given_std**2
    scales = []
    for i in range(int(seconds * fps)):
        t = i / fps
        walker = np.array([5 + 2 * np.cos(t / 3), 5 + 2 * np.sin(t / 3)])
        truth = np.stack([walker, [2.0, 2.0]])
        z = truth + rng.normal(0, true_std, truth.shape)
        tracker.update(t, z, [Origin(cameras=(0, 1))] * 2, covariances=[given, given])
        scales.append(tracker.noise_scale.value)
    return scales


@pytest.mark.parametrize("fps", [4.0, 15.0, 30.0])
def test_the_scale_settles_where_the_covariances_describe_the_errors(fps: float) -> None:
    """Covariances 2.5x overconfident in std: the scale, started below its floor (raised to 3
    at the first step), settles a little under 2.5² = 6.25 (the filter's own prediction
    covariance takes part of the innovation), the same at any frame rate; honest covariances
    started at 9 come down to the floor."""
    options = {**RECOMMENDED, "measurement_scale": 1.0}
    over = walk_and_stand(Tracker(fps_hint=fps, **options), fps, 90, 0.15, 0.06)
    settled = np.median(over[len(over) // 2 :])
    assert 3.5 < settled < 8.0, settled
    honest = walk_and_stand(Tracker(fps_hint=fps, **RECOMMENDED), fps, 90, 0.06, 0.06)
    assert np.median(honest[len(honest) // 2 :]) == MIN_SCALE < RECOMMENDED["measurement_scale"]


def test_a_fixed_scale_stays_and_an_empty_room_does_not_move_it() -> None:
    fixed = Tracker(fps_hint=15, **{**RECOMMENDED, "adapt_scale_s": 0.0})
    assert set(walk_and_stand(fixed, 15, 10, 0.3, 0.03)) == {RECOMMENDED["measurement_scale"]}
    empty = Tracker(fps_hint=15, **RECOMMENDED)
    for i in range(150):
        empty.update(i / 15, np.zeros((0, 2)))
    assert empty.noise_scale.value == RECOMMENDED["measurement_scale"]


def test_wild_innovations_move_the_median_tracker_no_faster_than_its_time_constant() -> None:
    scale = NoiseScale(initial=3.0, time_constant_s=10.0)
    for _ in range(40):  # 10 s at 4 fps, every innovation far out
        for _ in range(5):
            scale.observe(1e6)
        scale.step(0.25)
    assert scale.value == pytest.approx(12.0)  # log 4 per time constant, whatever d² is
    for _ in range(400):
        scale.observe(1e6)
        scale.step(1.0)
    assert scale.value == MAX_SCALE
    for _ in range(400):
        scale.observe(CHI2_2_MEDIAN / 2)
        scale.step(1.0)
    assert scale.value == MIN_SCALE
    with pytest.raises(ValueError, match="initial"):
        NoiseScale(0.0, 10.0)


def test_a_lying_persons_position_keeps_the_starting_scale() -> None:
    """With the scale learned down to its floor, a lying body's box (``Origin.standing``
    false), 1 m off along a lone camera's line of sight, drags its track less than a standing
    person's box would, and teaches the scale nothing."""
    moved = {}
    sight = np.diag([0.6**2, 0.09**2])  # a lone view: long along x
    for standing in (True, False):
        tracker = Tracker(fps_hint=10, **RECOMMENDED)
        tracker.noise_scale.value = MIN_SCALE  # as learned in a room of people standing apart
        both = [Origin(cameras=(0, 1))]
        for i in range(20):  # 2 s seen by both cameras (not yet still: that takes 5 s)
            tracks = tracker.update(i / 10, np.array([[2.0, 2.0]]), both, covariances=[sight / 4])
        for i in range(20, 30):
            lone = [Origin(cameras=(0,), standing=standing)]
            tracks = tracker.update(i / 10, np.array([[3.0, 2.0]]), lone, covariances=[sight])
        assert tracker.noise_scale.value == MIN_SCALE or standing
        (track,) = tracks
        moved[standing] = track.x - 2.0
    assert 0 < moved[False] < 0.7 * moved[True], moved
