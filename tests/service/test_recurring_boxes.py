"""Places where a camera keeps reading lying (service.tracking.recurring_boxes): learned per camera
from separate episodes of its lying boxes, and no evidence of a body on the floor there
(posture.normalise, the chain)."""

from __future__ import annotations

import numpy as np
import pytest

from models.detector.base import Detections
from service.tracking import posture
from service.tracking.posture import LYING, SITTING, UNKNOWN
from service.tracking.recurring_boxes import RecurringBoxes
from tests.service.test_posture import _area, _each_box, _RowMapCamera

SHORT = [300.0, 400.0, 330.0, 450.0]  # a 50 px box with its bottom centre at (315, 450)


def _report(memory: RecurringBoxes, start: float, seconds: float, box: list[float]) -> list[bool]:
    """``box`` reported by camera 0 every 0.2 s for ``seconds`` from ``start``; whether it was
    at a recurring place each time."""
    return [
        bool(memory.update(start + 0.2 * i, 0, np.array([box]))[0])
        for i in range(round(seconds / 0.2))
    ]


def test_a_box_that_keeps_coming_back_is_recurring_from_its_third_episode() -> None:
    memory = RecurringBoxes()
    assert not any(_report(memory, 0.0, 1.0, SHORT))
    # back 12 s later (a new episode), twice as wide and 8 % taller: a detector's false box at
    # one spot changes width more than height
    wider = [293.0, 396.0, 337.0, 450.0]
    assert not any(_report(memory, 13.0, 1.0, wider))
    assert all(_report(memory, 26.0, 1.0, SHORT))


def test_one_body_through_detector_dropouts_is_one_episode() -> None:
    """A body on the floor seen for a minute with dropouts of up to 8 s (under ``gap_s``) is
    one episode: its own lying reads are never doubted."""
    memory = RecurringBoxes()
    seen: list[bool] = []
    for start in np.arange(0.0, 60.0, 9.0):
        seen += _report(memory, float(start), 1.0, SHORT)
    assert not any(seen)


def test_other_places_and_sizes_do_not_match() -> None:
    memory = RecurringBoxes()
    for start in (0.0, 13.0, 26.0):
        _report(memory, start, 1.0, SHORT)
    standing = [305.0, 250.0, 325.0, 450.0]  # a walker on the same spot: 4 times as tall
    aside = [330.0, 400.0, 360.0, 450.0]  # the same box 30 px to the side (0.6 of its height)
    recurring = memory.update(40.0, 0, np.array([SHORT, standing, aside]))
    assert recurring.tolist() == [True, False, False]
    # each camera learns its own places
    assert memory.update(41.0, 1, np.array([SHORT])).tolist() == [False]


def test_places_are_forgotten_and_bounded() -> None:
    memory = RecurringBoxes(forget_s=60.0, max_places=4)
    for start in (0.0, 13.0, 26.0):
        _report(memory, start, 1.0, SHORT)
    assert memory.update(80.0, 0, np.array([SHORT])).tolist() == [True]
    assert memory.update(200.0, 0, np.array([SHORT])).tolist() == [False]  # unseen 2 min
    for start in (213.0, 226.0):
        _report(memory, start, 0.2, SHORT)
    others = np.array([[20.0 + 50 * i, 100.0, 40.0 + 50 * i, 150.0] for i in range(10)])
    memory.update(230.0, 0, others)  # ten one-off boxes elsewhere: the least seen places go
    assert memory.update(240.0, 0, np.array([SHORT])).tolist() == [True]


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="episodes"):
        RecurringBoxes(episodes=1)


def test_a_lying_box_at_a_recurring_place_is_no_lying_evidence() -> None:
    flat = [200.0, 385.0, 360.0, 465.0]  # 0.4 of a standing height, twice as wide: lying
    seated = [300.0, 100.0, 380.0, 230.0]
    det = Detections(np.array([flat, seated], np.float32), np.ones(2, np.float32))
    size = np.array([[640, 480]])
    asked: list[tuple[int, list[list[float]]]] = []

    def doubt(camera: int, boxes: np.ndarray) -> np.ndarray:
        asked.append((camera, boxes.tolist()))
        return np.ones(len(boxes), bool)

    _, postures = posture.normalise([det], _area(), size)
    assert postures.labels[0].tolist() == [LYING, SITTING]
    fixed, postures = posture.normalise([det], _area(), size, doubt)
    # only the lying box is asked about; read unknown and kept as detected
    assert asked == [(0, [flat])]
    assert postures.labels[0].tolist() == [UNKNOWN, SITTING]
    assert postures.confidence[0][0] == 0.0
    assert fixed[0].boxes[0] == pytest.approx(flat)


def test_the_chain_stops_reading_a_returning_box_as_a_body_on_the_floor() -> None:
    """A flat box one camera reports for 1.5 s at a time, every 13 s, at one place (a bag, a
    rug): served lying the first two times, as a body would be; the third time it is read as
    detected (beyond the set-up area here) and no lying person is served."""
    from service.pipeline.chain import Chain
    from service.tracking.tracker import RECOMMENDED, Tracker

    chain = Chain(
        Tracker(fps_hint=10, **RECOMMENDED),
        associate=_each_box,  # type: ignore[arg-type]
        view_bias=None,
    )
    boxes = np.array([[200.0, 385.0, 360.0, 465.0]], np.float32)
    detected = [Detections(boxes, np.ones(1, np.float32))]
    nothing = [Detections.empty()]
    runtime = _RowMapCamera()
    lying: list[bool] = []
    for episode in range(3):
        start = 13.0 * episode
        for i in range(15):
            _, tracks = chain(start + i / 10, detected, runtime, [True], i)  # type: ignore[arg-type]
        lying.append(any(t.posture is not None and t.posture[0] == LYING for t in tracks))
        chain(start + 6.0, nothing, runtime, [True], 99)  # type: ignore[arg-type]
    assert lying == [True, True, False]
