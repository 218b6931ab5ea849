"""The move step ends when the person has moved and then stands still on the next mark."""

from __future__ import annotations

import numpy as np
import pytest

from service.setup.arrival import Arrival

FPS = 15
NONE = np.zeros((0, 4))


def box(u: float, bottom: float, height: float) -> np.ndarray:
    return np.array([[u - 0.2 * height, bottom - height, u + 0.2 * height, bottom]])


def walk_then_stand(rng: np.random.Generator, scale: float, misses: float = 0.0) -> list:
    """Per frame the boxes of one camera: 1.5 s still on the old mark (a late reaction), 2 s
    walking sideways (half a body height per second), then standing on the new mark."""
    frames = []
    for i in range(10 * FPS):
        t = i / FPS
        u = 200 + 100 * min(max(t - 1.5, 0.0), 2.0)
        noisy = box(u + 8 * rng.standard_normal(), 400 + 8 * rng.standard_normal(), 200)
        frames.append((t, NONE if rng.random() < misses else noisy * scale))
    return frames


def arrival_time(frames: list, false_every: int = 0) -> float | None:
    arrival = Arrival(2)
    for i, (t, boxes) in enumerate(frames):
        other = box(500, 300, 120) if false_every and i % false_every == 0 else NONE
        if arrival.update(t, [boxes, other]):
            return t
    return None


@pytest.mark.parametrize("scale", [0.25, 1.0, 6.0])
def test_arrives_soon_after_stopping_never_while_walking(scale: float) -> None:
    t = arrival_time(walk_then_stand(np.random.default_rng(2), scale))
    assert t is not None and 3.5 + 0.3 <= t <= 3.5 + 1.6, t  # the walk ends at 3.5 s


def test_a_measured_detectors_misses_and_false_boxes_still_arrive() -> None:
    frames = walk_then_stand(np.random.default_rng(3), 1.0, misses=0.3)
    t = arrival_time(frames, false_every=4)
    assert t is not None and t <= 3.5 + 2.5, t


def test_nobody_moving_or_two_people_never_arrive() -> None:
    rng = np.random.default_rng(4)
    still = [(i / FPS, box(300 + 3 * rng.standard_normal(), 400, 200)) for i in range(5 * FPS)]
    assert arrival_time(still) is None  # still on the previous mark: not moved yet
    arrival = Arrival(1)
    frames = walk_then_stand(rng, 1.0)
    two = [arrival.update(t, [np.concatenate([b, box(50, 450, 150)])]) for t, b in frames]
    assert not any(two)
