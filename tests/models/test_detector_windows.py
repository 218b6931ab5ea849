"""Windows around known small people: geometry of the plan, recovery of people the full pass
misses, and nothing lost when a window finds nobody."""

from __future__ import annotations

import numpy as np
import pytest

from models.detector import Detections, create_detector
from models.detector.base import PersonDetector
from models.detector.preprocessing import box_iou
from models.detector.validation import background, person_frame
from models.detector.windows import WindowRefiner, plan_windows


@pytest.fixture(scope="module")
def detector():
    return create_detector("nanodet")


@pytest.fixture(scope="module")
def refiner(detector):
    return WindowRefiner(detector.resized((96, 160)))


def test_windows_have_the_input_aspect_the_context_and_stay_inside_the_frame():
    priors = [
        np.array([[100, 100, 120, 150], [0, 400, 30, 478], [10, 10, 200, 400]], np.float32),
        np.array([[np.nan] * 4, [620, 0, 640, 40]], np.float32),
    ]
    windows = plan_windows(priors, [(640, 480), (640, 480)], 0.6, 1.6, 120, min_window=48)
    assert [w.frame for w in windows] == [0, 0, 1]  # the 390 px box and the NaN row are skipped
    for window in windows:
        x0, y0, x1, y1 = window.rect
        assert 0 <= x0 < x1 <= 640 and 0 <= y0 < y1 <= 480
        assert (x1 - x0) / (y1 - y0) == pytest.approx(0.6, abs=0.03)
    assert windows[0].rect[3] - windows[0].rect[1] == 80  # 1.6 × the 50 px box, centred
    assert windows[0].rect[1] == 85
    assert windows[1].rect[3] == 480  # shifted up to stay inside, not shrunk
    assert windows[2].rect[3] - windows[2].rect[1] == 64  # 1.6 × 40


@pytest.mark.parametrize("height", [50, 60])
def test_a_small_person_the_full_pass_misses_is_found_in_its_window(detector, refiner, height):
    frame, truth = person_frame("camera", height, anchor=(0.1, 0.9))
    full = detector.detect([frame])
    assert not len(full[0]) or box_iou(truth, full[0].boxes).max() < 0.5
    prior = truth + np.array([4, -3, 4, 5], np.float32)  # where the tracker expects the person
    (refined,) = refiner([frame], full, [prior[None]])
    assert len(refined) == 1
    assert box_iou(truth, refined.boxes)[0, 0] > 0.7


def test_the_window_box_replaces_the_coarse_full_frame_box(detector, refiner):
    frame, truth = person_frame("astronaut", 100, anchor=(0.9, 0.6))
    full = detector.detect([frame])
    (refined,) = refiner([frame], full, [full[0].boxes])
    assert len(refined) == len(full[0]) == 1
    assert box_iou(truth, refined.boxes)[0, 0] > box_iou(truth, full[0].boxes)[0, 0]


def test_a_window_that_finds_nobody_drops_nothing(detector, refiner):
    empty = background(3)
    kept = Detections(np.array([[300, 200, 330, 260]], np.float32), np.array([0.5], np.float32))
    (result,) = refiner([empty], [kept], [kept.boxes])
    np.testing.assert_array_equal(result.boxes, kept.boxes)
    (untouched,) = refiner([empty], [kept], [np.zeros((0, 4), np.float32)])
    assert untouched is kept


def test_the_number_of_windows_is_bounded_smallest_first(detector):
    refiner = WindowRefiner(detector.resized((96, 160)), max_windows=2)
    seen: list[int] = []

    class Counting(PersonDetector):
        input_size = (96, 160)

        def detect(self, crops):
            seen.extend(crop.shape[0] for crop in crops)
            return [Detections.empty() for _ in crops]

    refiner.detector = Counting()
    priors = np.array([[0, 0, 10, 100], [50, 0, 60, 40], [100, 0, 110, 70]], np.float32)
    refiner([background(0)], [Detections.empty()], [priors])
    assert seen == [64, 112]  # the 40 px and 70 px boxes; the 100 px one waits
