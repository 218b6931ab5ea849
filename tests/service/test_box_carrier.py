"""Box carrier: constant-velocity following (filter and flow), late detections, expiry."""

from __future__ import annotations

import numpy as np
import pytest

from service.detection.box_carrier import BoxCarrier, box_iou
from tests.service.fake_frames import FPS, draw, moving_box


def _detected_then_carried(carrier: BoxCarrier, detected: int, carried: int, images: bool):
    """Detections on frames 0..detected-1, then carried boxes (frame, box, age) after."""
    for i in range(detected):
        box = moving_box(i)
        carrier.advance(i / FPS, draw([box]) if images else None)
        carrier.correct(i / FPS, box[None], np.array([0.9]))
    out = []
    for i in range(detected, detected + carried):
        result = carrier.advance(i / FPS, draw([moving_box(i)]) if images else None)
        out.append((i, result))
    return out


@pytest.mark.parametrize("flow", [False, True])
def test_carried_box_follows_constant_velocity(flow: bool) -> None:
    carrier = BoxCarrier(flow=flow, max_age_s=1.0)
    for i, result in _detected_then_carried(carrier, 8, 8, images=flow):
        assert len(result) == 1
        error = np.abs(result.boxes[0] - moving_box(i)).max()
        assert error < 3.0, (i, result.boxes[0], moving_box(i))
        assert result.age[0] == pytest.approx((i - 7) / FPS, abs=1e-6)


def test_box_that_is_held_still_falls_behind() -> None:
    """The check above can fail: without velocity the box lags by 4 px per frame."""
    carrier = BoxCarrier(flow=False, accel=1e-9, max_age_s=1.0)
    carrier.correct(0.0, moving_box(0)[None])
    result = carrier.advance(5 / FPS)
    assert np.abs(result.boxes[0] - moving_box(5)).max() > 15


def test_flow_follows_a_turn_the_filter_cannot_predict() -> None:
    """After the box reverses, flow sees the new motion; the filter alone keeps going the old way.

    Flow is weighted like a detection (3 % of box height), so it bends the track rather than
    snapping it: trusting it more was worse on real video (bench/serving/realtime.py)."""
    errors = {}
    for flow in (False, True):
        carrier = BoxCarrier(flow=flow, max_age_s=2.0)
        for i in range(8):
            box = moving_box(i)
            carrier.advance(i / FPS, draw([box]))
            carrier.correct(i / FPS, box[None])
        turned = moving_box(7)
        for j in range(1, 7):  # now moving left at 4 px per frame
            turned = turned + np.array([-4, 0, -4, 0], np.float32)
            result = carrier.advance((7 + j) / FPS, draw([turned]))
        errors[flow] = float(np.abs(result.boxes[0] - turned).max())
    assert errors[True] < 0.7 * errors[False]


def test_late_detection_corrects_the_current_box_without_a_duplicate() -> None:
    carrier = BoxCarrier(flow=False, max_age_s=1.0)
    carrier.correct(0.0, moving_box(0)[None])
    for i in range(1, 6):
        carrier.advance(i / FPS)
    # the detector's result for frame 3 arrives now (frame 5): same person, box 5 px to the right
    carrier.correct(3 / FPS, (moving_box(3) + np.array([5, 0, 5, 0], np.float32))[None])
    result = carrier.current()
    assert len(result) == 1
    assert result.age is not None and result.age[0] == pytest.approx(2 / FPS, abs=1e-6)
    held = moving_box(0)
    assert result.boxes[0][0] > held[0] + 4  # moved towards the late measurement


def test_new_person_from_a_late_detection_is_caught_up_by_flow() -> None:
    for flow, expect_close in ((True, True), (False, False)):
        carrier = BoxCarrier(flow=flow)
        for i in range(7):
            carrier.advance(i / FPS, draw([moving_box(i)]))
        carrier.correct(3 / FPS, moving_box(3)[None])  # found in frame 3, known at frame 6
        error = np.abs(carrier.current().boxes[0] - moving_box(6)).max()
        assert (error < 3.0) == expect_close, (flow, error)


def test_stale_boxes_expire_by_age() -> None:
    carrier = BoxCarrier(flow=False, max_age_s=0.5, max_misses=100)
    carrier.correct(0.0, moving_box(0)[None])
    assert len(carrier.advance(0.4)) == 1
    assert len(carrier.advance(0.6)) == 0


def test_boxes_missed_by_the_detector_expire() -> None:
    carrier = BoxCarrier(flow=False, max_age_s=10.0, max_misses=2)
    carrier.correct(0.0, moving_box(0)[None])
    empty = np.zeros((0, 4), np.float32)
    for i in range(1, 4):
        carrier.advance(i / FPS)
        carrier.correct(i / FPS, empty)
        assert len(carrier.current()) == (1 if i <= 2 else 0)


def test_keypoints_move_with_their_box() -> None:
    carrier = BoxCarrier(flow=False, max_age_s=1.0)
    keypoints = np.zeros((1, 17, 3), np.float32)
    keypoints[0, :, 0], keypoints[0, :, 1], keypoints[0, :, 2] = 130.0, 300.0, 0.8  # bottom middle
    for i in range(6):
        box = moving_box(i)
        carrier.advance(i / FPS)
        kp = keypoints + np.array([4 * i, i, 0], np.float32)
        carrier.correct(i / FPS, box[None], np.array([0.9]), kp)
    result = carrier.advance(9 / FPS)
    assert result.keypoints is not None
    np.testing.assert_allclose(result.keypoints[0, 0, :2], [130 + 36, 300 + 9], atol=3.0)
    assert result.keypoints[0, 0, 2] == pytest.approx(0.8)


def test_box_iou() -> None:
    a = np.array([[0, 0, 10, 10]], float)
    b = np.array([[0, 0, 10, 10], [5, 0, 15, 10], [20, 20, 30, 30]], float)
    np.testing.assert_allclose(box_iou(a, b), [[1.0, 1 / 3, 0.0]])
