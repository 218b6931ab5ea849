"""The shipped detector on real photographs (scikit-image's bundled ones) pasted into 640×480."""

from __future__ import annotations

import numpy as np
import pytest

from models.detector import create_detector
from models.detector.preprocessing import box_iou
from models.detector.validation import NO_PEOPLE, background, paste, person_frame, photo

ANCHORS = [(0.0, 1.0), (0.5, 0.5), (1.0, 1.0)]


@pytest.fixture(scope="module")
def detector():
    return create_detector("ssdlite")


@pytest.mark.parametrize(
    ("name", "height"),
    [("astronaut", 340), ("astronaut", 480), ("camera", 160), ("camera", 260), ("camera", 480)],
)
def test_finds_the_person_with_the_right_box(detector, name, height):
    cases = [person_frame(name, height, anchor) for anchor in ANCHORS]
    results = detector.detect([frame for frame, _ in cases])
    for (_, truth), found in zip(cases, results, strict=True):
        assert len(found) == 1, f"{name} {height}px: {len(found)} detections"
        assert box_iou(truth, found.boxes)[0, 0] > 0.6
        assert found.scores[0] > 0.5


def test_wrong_box_would_fail(detector):
    """Guard against a vacuous IoU check: a box shifted by its own width scores far below 0.6."""
    frame, truth = person_frame("camera", 300, (0.0, 1.0))
    (found,) = detector.detect([frame])
    shifted = found.boxes + np.array([1, 0, 1, 0]) * (found.boxes[:, 2:3] - found.boxes[:, 0:1])
    assert box_iou(truth, shifted)[0, 0] < 0.2


@pytest.mark.parametrize("name", NO_PEOPLE)
def test_finds_nobody_in_photographs_without_people(detector, name):
    image = photo(name)
    fit = min(640 / image.shape[1], 480 / image.shape[0])
    frames = [paste(image, background(), scale, (0.5, 0.5))[0] for scale in (fit, fit / 2)]
    assert [len(found) for found in detector.detect(frames)] == [0, 0]
