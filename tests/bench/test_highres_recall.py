"""The high-resolution bench's pure pieces (bench/detector/highres_recall.py): the frame rebuilding
keeps
every box on its person's pixels, and the report is computed from the rows it is given."""

from __future__ import annotations

import numpy as np
import pytest

from bench.detector.data import Sample
from bench.detector.highres_recall import Row, rebuilt, report
from bench.detector.metrics import Truth, evaluate

PERSON = (101, 37, 143, 221)  # xmin, ymin, xmax, ymax in the 640×480 frame


def drawn_person() -> Sample:
    """A dark 640×480 frame with one white rectangle exactly where its true box says."""
    image = np.full((480, 640, 3), 20, np.uint8)
    x0, y0, x1, y1 = PERSON
    image[y0:y1, x0:x1] = 255
    return Sample("fake", image, Truth.of([PERSON], truncated=[False]))


def white_box(image: np.ndarray) -> np.ndarray:
    """The rectangle's box in continuous pixel edges: columns/rows at least half white."""
    ys, xs = np.nonzero(image[..., 0] > (255 + 20) / 2)
    return np.array([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1], float)


@pytest.mark.parametrize(
    ("size", "scale", "left"), [((1280, 720), 1.5, 160), ((1920, 1080), 2.25, 240)]
)
def test_rebuilt_frame_keeps_the_box_on_the_person(
    size: tuple[int, int], scale: float, left: int
) -> None:
    sample = rebuilt(drawn_person(), size)
    assert sample.image.shape == (size[1], size[0], 3)
    expected = np.array(PERSON, float) * scale + [left, 0, left, 0]
    np.testing.assert_allclose(sample.truth.boxes[0], expected)
    # The box sits on the drawn pixels (within a pixel of interpolation blur).
    np.testing.assert_allclose(white_box(sample.image), sample.truth.boxes[0], atol=1.0)
    # Grey bars left and right of the picture (dark background) in between.
    assert (sample.image[:, :left] == 114).all() and (
        sample.image[:, size[0] - left :] == 114
    ).all()
    assert (sample.image[:, [left, size[0] - left - 1]] == 20).all()
    assert not sample.truth.truncated[0]


def test_rebuilding_at_the_same_size_changes_nothing() -> None:
    original = drawn_person()
    same = rebuilt(original, (640, 480))
    np.testing.assert_array_equal(same.image, original.image)
    np.testing.assert_array_equal(same.truth.boxes, original.truth.boxes)


def fake_row(data: str, frame: tuple[int, int], shrink: float | None, cpu_ms: float) -> Row:
    """Two people, 150 and 300 px tall at 1080 (67 and 133 px in 640×480 terms); the setting
    with a larger input finds both, the fixed input only the tall one plus a false box."""
    truth = Truth.of([[100, 100, 140, 250], [500, 100, 600, 400]])
    if shrink is None:
        boxes, scores = np.array([[500, 100, 600, 400], [900, 0, 950, 90]]), np.array([0.9, 0.5])
    else:
        boxes, scores = truth.boxes, np.array([0.9, 0.8])
    small = 100.0 * frame[1] / 480 if data == "vtest" else 100.0
    size = (320, 256) if shrink is None else (640, 384)
    return Row(
        data, frame, shrink, size, evaluate([(truth, boxes, scores)], 0.4, 0.5), small, cpu_ms
    )


def test_report_is_computed_from_the_rows() -> None:
    rows = [
        fake_row("vtest", (640, 480), None, 10.0),
        fake_row("vtest", (1920, 1080), None, 12.0),
        fake_row("vtest", (1920, 1080), 3.0, 25.0),
        fake_row("drawn", (1920, 1080), None, 11.0),
        fake_row("drawn", (1920, 1080), 3.0, 30.0),
    ]
    text = report(
        rows, {"vtest": 3, "drawn": 1}, "python -m bench.detector.highres_recall", "openvino int8"
    )
    lines = text.splitlines()
    assert "median per frame on one openvino int8 thread" in text
    assert lines[0].startswith("# ")
    assert "`python -m bench.detector.highres_recall`" in text and "UTC" in text
    reading = next(line for line in lines if line.startswith("**Reading.**"))
    # The CPU ratio against fixed @ 640×480 (25 / 10) and the recalls come from the rows.
    assert "max_shrink 3 (640x384) finds 1.00 (under 100 px 1.00) at precision 1.00 for 2.5×" in (
        reading
    )
    assert "fixed 320x256 finds 0.50 (under 100 px 0.00) at precision 0.50" in reading
    assert "(2 people, 1 under 100 px)" in reading
    assert "Most people found with max_shrink 3, highest precision with max_shrink 3." in reading
    table = [line for line in lines if line.startswith("| 1920x1080 | max_shrink 3 |")]
    assert table == [
        "| 1920x1080 | max_shrink 3 | 640x384 | 1.00 (2) | 1.00 (1) | 1.00 | 0.00 | 25.0 | 2.50 |"
    ]
    # 150 px at 1080 is small in 640×480 terms (67 px); 300 px (133 px) is not.
    fixed = next(line for line in lines if line.startswith("| 1920x1080 | fixed 320x256 |"))
    assert "| 0.50 (2) | 0.00 (1) | 0.50 | 1.00 | 12.0 | 1.20 |" in fixed
    drawn = next(line for line in lines if line.startswith("| max_shrink 3 | 640x384 |"))
    assert drawn.startswith("| max_shrink 3 | 640x384 | nan (0) | 1.00 (1) | 1.00 (1) | 1.00 (2) |")
