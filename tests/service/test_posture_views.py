"""A person two cameras see compact is lying when only the lying reading makes the views agree
(service.tracking.posture_views)."""

from __future__ import annotations

import numpy as np
import pytest

from models.detector.base import Detections
from models.mom.setup_area import CameraRegion, SetupArea
from service.stages import Association
from service.tracking import posture
from service.tracking.posture import LYING, SITTING
from service.tracking.posture_views import lying_by_views

STANDING_PX = 200.0  # a person standing anywhere looks 200 px tall to both cameras
SIZES = np.array([[1000.0, 1000.0], [1000.0, 1000.0]])


def _area() -> SetupArea:
    flat = np.array([np.log(STANDING_PX), 0, 0, 0, 0, 0], float)
    hull = np.array([[0.0, 0.0], [1000.0, 0.0], [1000.0, 1000.0], [0.0, 1000.0]])
    region = CameraRegion(hull, (50.0, 900.0), flat, 0.05)
    return SetupArea(np.array([[0.0, 0.0], [9.0, 0.0], [9.0, 9.0]]), 0.5, (region, region))


class _TwoCameras:
    """A localizer double: camera 0 looks along x (a box's bottom row v stands at x = v / 50 m,
    its centre column u at y = u / 100 m), camera 1 along y (bottom row v at y = v / 50 m,
    column u at x = u / 100 m); seen by both, the mean of the two."""

    observation = "bbox"

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        boxes = np.asarray(boxes, float)
        column = 0.5 * (boxes[..., 0] + boxes[..., 2]) / 100.0
        row = boxes[..., 3] / 50.0
        by_camera = np.stack(
            [np.stack([row[:, 0], column[:, 0]], 1), np.stack([column[:, 1], row[:, 1]], 1)], 1
        )
        return np.nanmean(by_camera, axis=1)

    def covariance(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        return np.tile(0.01 * np.eye(2), (len(boxes), 1, 1))


def _associated(box0: list[float], box1: list[float]) -> tuple:
    """The two boxes detected, converted as their shape says and associated together."""
    detected = [Detections(np.array([b], np.float32), np.ones(1, np.float32)) for b in (box0, box1)]
    normalised, postures = posture.normalise(detected, _area(), SIZES)
    rows = np.stack([np.asarray(d.boxes[0], np.float64) for d in normalised])
    runtime = _TwoCameras()
    found = [Association(rows, [0, 1], runtime.localize(rows[None])[0], 0.0, [0, 0])]
    return detected, found, postures


# Compact boxes (70 px: 0.35 of a standing height, 100 px wide) read sitting. Seated, a box's
# top is a head 128 px (0.64 of a standing height) above the feet; lying, the floor under the
# body's middle is 0.7 down the box (49 px below its top).
# A body lying at (5.26, 3.5): camera 0's lying reading is row 263 (x 5.26), column 350 (y 3.5);
# camera 1's row 175 (y 3.5), column 526 (x 5.26). Their seated readings, (6.84, 3.5) and
# (5.26, 5.08), are 2.23 m apart.
LYING_0 = [300.0, 214.0, 400.0, 284.0]
LYING_1 = [476.0, 126.0, 576.0, 196.0]
# A person seated at (6.84, 3.5): camera 1's box with its feet row (top + 128) at 175 (y 3.5),
# column 684 (x 6.84); its lying reading is row 96 (y 1.92), 2.23 m from camera 0's.
SEATED_1 = [634.0, 47.0, 734.0, 117.0]


def test_two_compact_views_that_agree_only_as_lying_are_a_body_on_the_floor() -> None:
    detected, found, postures = _associated(LYING_0, LYING_1)
    assert [postures.labels[k][0] for k in (0, 1)] == [SITTING, SITTING]
    (read,) = lying_by_views(found, detected, postures, _area(), _TwoCameras())
    assert read.world == pytest.approx([5.26, 3.5])
    assert postures.of(read.detection_index)[0] == LYING
    assert postures.confidence[0][0] == pytest.approx(0.734)  # seated 2.234 m: 0.234 beyond


def test_a_seated_person_whose_views_agree_as_seated_stays_seated() -> None:
    detected, found, postures = _associated(LYING_0, SEATED_1)
    before = found[0].world.copy()
    (read,) = lying_by_views(found, detected, postures, _area(), _TwoCameras())
    assert read.world == pytest.approx(before)
    assert read.world == pytest.approx([6.84, 3.5])
    assert postures.of(read.detection_index)[0] == SITTING


def test_a_mixed_vote_is_converted_wholly_as_lying_when_the_views_agree_so() -> None:
    """Camera 0 sees the body across (a flat box, read lying), camera 1 lengthwise (read
    sitting): voted lying already, but camera 1's box kept its seated conversion, 1.58 m off."""
    flat_0 = [250.0, 236.0, 450.0, 288.0]  # 52 px high, 200 wide: lying, floor row 272
    detected, found, postures = _associated(flat_0, LYING_1)
    assert [postures.labels[k][0] for k in (0, 1)] == [LYING, SITTING]
    assert found[0].world[1] == pytest.approx(0.5 * (3.5 + 5.08))  # the seated box pulls it
    (read,) = lying_by_views(found, detected, postures, _area(), _TwoCameras())
    assert read.world == pytest.approx([0.5 * (272.4 / 50 + 5.26), 3.5])
    assert postures.labels[1][0] == LYING


@pytest.mark.parametrize(
    "box0, box1",
    [
        (LYING_0, [476.0, 20.0, 576.0, 202.0]),  # camera 1 sees a standing person: not compact
        (LYING_0, [476.0, 164.0, 576.0, 234.0]),  # lying readings 0.76 m apart: a squat's
        # agreeing as lying, but the seated readings only 1.84 m apart: a squat seen from both
        # sides near the cameras' wall (the fall bench's set 1301 had one)
        ([300.0, 200.0, 400.0, 290.0], [476.0, 112.0, 576.0, 202.0]),
    ],
)
def test_views_that_do_not_agree_as_lying_keep_their_reading(
    box0: list[float], box1: list[float]
) -> None:
    detected, found, postures = _associated(box0, box1)
    labels = [str(postures.labels[k][0]) for k in (0, 1)]
    before = found[0].world.copy()
    (read,) = lying_by_views(found, detected, postures, _area(), _TwoCameras())
    assert read.world == pytest.approx(before)
    assert [str(postures.labels[k][0]) for k in (0, 1)] == labels


def test_a_lone_view_is_left_to_the_continuity_reading() -> None:
    detected, found, postures = _associated(LYING_0, LYING_1)
    rows = found[0].boxes.copy()
    rows[1] = np.nan
    alone = [Association(rows, [0], found[0].world, 0.0, [0, None])]
    (read,) = lying_by_views(alone, detected, postures, _area(), _TwoCameras())
    assert read is alone[0]
    assert postures.labels[0][0] == SITTING


def test_a_squat_whose_feet_agree_better_than_its_lying_readings_stays_seated() -> None:
    """Seen from both sides near the cameras' wall, a squat's lying readings can agree (0.31 m
    here) while its seated ones land 2 m apart, as a body's do; but its boxes' bottoms are its
    feet, and those agree better still (0.25 m)."""
    squat_0 = [310.0, 193.0, 390.0, 259.0]  # 66 px tall: feet at (5.18, 3.5)
    squat_1 = [460.0, 118.0, 540.0, 184.0]  # feet at (5.0, 3.68)
    detected, found, postures = _associated(squat_0, squat_1)
    assert [postures.labels[k][0] for k in (0, 1)] == [SITTING, SITTING]
    before = found[0].world.copy()
    (read,) = lying_by_views(found, detected, postures, _area(), _TwoCameras())
    assert read.world == pytest.approx(before)
    assert postures.of(read.detection_index)[0] == SITTING
