"""Calibrated baseline: geometry on hand-built cameras, DLT calibration, chessboard noise."""

from __future__ import annotations

import numpy as np
import pytest

from common.errors import MomlocError
from models.geometry import calibrated_baseline as baseline
from models.geometry.dlt import fit_dlt

F, CX, CY = 500.0, 320.0, 240.0
SIZE = np.array([[640, 480]] * 3)


def _camera(eye: tuple[float, float, float], target: tuple[float, float, float]) -> np.ndarray:
    """P = K [R | t] for a camera at ``eye`` looking at ``target`` with no roll."""
    eye_, forward = np.array(eye), np.array(target) - np.array(eye)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0, 1])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rot = np.stack([right, down, forward])
    k = np.array([[F, 0, CX], [0, F, CY], [0, 0, 1]])
    return k @ np.concatenate([rot, (-rot @ eye_)[:, None]], axis=1)


# Level cameras (looking horizontally): vertical world lines stay vertical in the image and image
# rows are linear in height, so the exact box of a thin upright person has its centre on the
# projection of (x, y, h/2) and its bottom-centre on the projection of the floor point.
LEVEL = np.stack(
    [
        _camera((0.0, -4.0, 0.9), (0.0, 0.0, 0.9)),
        _camera((5.0, 1.0, 0.9), (0.0, 1.0, 0.9)),
        _camera((-4.0, 4.0, 0.9), (1.0, 0.0, 0.9)),
    ]
)
TILTED = np.stack(
    [
        _camera((0.0, -4.0, 2.4), (0.0, 1.0, 0.0)),
        _camera((5.0, 1.0, 2.2), (1.0, 1.0, 0.5)),
        _camera((-4.0, 4.0, 2.6), (1.0, 0.0, 0.0)),
    ]
)
PEOPLE = np.array([[0.2, 0.5], [1.3, -0.4], [-0.7, 1.6], [0.9, 2.1]])


def _exact_boxes(projections: np.ndarray, floor: np.ndarray, height: float = 1.7) -> np.ndarray:
    foot = np.concatenate([floor, np.zeros((len(floor), 1))], axis=1)
    head = foot + np.array([0.0, 0.0, height])
    boxes = []
    for p in projections:
        a, b = baseline.project(p, foot), baseline.project(p, head)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        pad = np.array([20.0, 0.0])
        boxes.append(np.concatenate([lo - pad, hi + pad], axis=1))
    return np.stack(boxes, axis=1)


@pytest.mark.parametrize("method", baseline.METHODS)
def test_exact_matrices_and_boxes_recover_the_position(method: str) -> None:
    boxes = _exact_boxes(LEVEL, PEOPLE)
    out = baseline.localize(boxes, LEVEL, method=method, image_size=SIZE)
    np.testing.assert_allclose(out, PEOPLE, atol=0.01)
    assert np.abs(out - PEOPLE).max() < 1e-6


def test_single_view_uses_the_foot_point() -> None:
    boxes = _exact_boxes(LEVEL, PEOPLE)
    boxes[:, 1:] = np.nan
    for method in baseline.METHODS:
        out = baseline.localize(boxes, LEVEL, method=method)
        np.testing.assert_allclose(out, PEOPLE, atol=1e-6)


def test_unseen_row_gives_nan() -> None:
    boxes = _exact_boxes(LEVEL, PEOPLE)
    boxes[2] = np.nan
    out = baseline.localize(boxes, LEVEL)
    assert np.isnan(out[2]).all() and np.isfinite(out[[0, 1, 3]]).all()


def test_triangulation_of_exact_points_with_tilted_cameras() -> None:
    rng = np.random.default_rng(1)
    points = rng.uniform([-1, -1, 0], [2, 2, 1.8], size=(50, 3))
    pixels = np.stack([baseline.project(p, points) for p in TILTED], axis=1)
    pixels[:10, 2] = np.nan  # two views are enough
    np.testing.assert_allclose(baseline.triangulate(TILTED, pixels), points, atol=1e-6)
    pixels[:5, 1] = np.nan  # one view is not
    assert np.isnan(baseline.triangulate(TILTED, pixels)[:5]).all()


def test_floor_backprojection_inverts_projection_and_rejects_the_sky() -> None:
    floor = np.concatenate([PEOPLE, np.zeros((4, 1))], axis=1)
    pixels = np.stack([baseline.project(p, floor) for p in TILTED], axis=1)
    back = baseline.floor_backproject(TILTED, pixels)
    np.testing.assert_allclose(back, np.repeat(PEOPLE[:, None], 3, axis=1), atol=1e-6)
    # A pixel at the top row of a level camera looks above the horizon: no floor point.
    sky = np.array([[[CX, 10.0]]])
    assert np.isnan(baseline.floor_backproject(LEVEL[:1], sky)).all()


def test_truncated_view_is_ignored_when_another_view_remains() -> None:
    boxes = _exact_boxes(LEVEL, PEOPLE)
    boxes[0, 0, 3] = 479.5  # bottom cut by the image border: the foot point lies
    out = baseline.localize(boxes, LEVEL, method="foot", image_size=SIZE)
    np.testing.assert_allclose(out[0], PEOPLE[0], atol=1e-6)
    biased = baseline.localize(boxes, LEVEL, method="foot")  # without the rule it is off
    assert np.linalg.norm(biased[0] - PEOPLE[0]) > 0.05


def _unit(p: np.ndarray) -> np.ndarray:
    p = p / np.linalg.norm(p)
    return p * np.sign(p[2, 3])


def test_dlt_calibration_recovers_p_up_to_scale() -> None:
    rng = np.random.default_rng(2)
    world = rng.uniform([-1, -1, 0], [2, 2, 1.5], size=(12, 3))
    for p in TILTED:
        est = fit_dlt(world, baseline.project(p, world))
        np.testing.assert_allclose(_unit(est), _unit(p), atol=1e-9)
        assert baseline.depth_sign(est, world).min() > 0


def test_dlt_calibration_refuses_coplanar_points() -> None:
    rng = np.random.default_rng(3)
    world = np.concatenate([rng.uniform(-1, 1, size=(10, 2)), np.zeros((10, 1))], axis=1)
    with pytest.raises(MomlocError, match="degenerate"):
        fit_dlt(world, baseline.project(TILTED[0], world))
    with pytest.raises(MomlocError, match=">= 6"):
        fit_dlt(world[:5], baseline.project(TILTED[0], world[:5]))


def test_chessboard_calibration_is_close_but_not_exact() -> None:
    rng = np.random.default_rng(4)
    area = rng.uniform([-1, -1], [2, 2], size=(200, 2))
    errors, exact = [], []
    for p in TILTED:
        perfect = baseline.ChessboardSetup(pixel_noise=0, placement_noise=0, tilt_noise_deg=0)
        clean = baseline.chessboard_calibration(p, (640, 480), area, rng, perfect)
        exact.append(np.abs(_unit(clean) - _unit(p)).max())
        noisy = baseline.chessboard_calibration(p, (640, 480), area, rng)
        probe = np.concatenate([area[:50], rng.uniform(0, 1.8, size=(50, 1))], axis=1)
        errors.append(
            np.linalg.norm(baseline.project(noisy, probe) - baseline.project(p, probe), axis=1)
        )
    assert max(exact) < 1e-8  # the simulated session itself is geometrically right
    err = np.concatenate(errors)
    assert 0.3 < np.median(err) < 30.0  # noise shows up as pixels of reprojection error
    # and the localization from noisy matrices is off by centimetres, not metres
    calibrated = np.stack(
        [baseline.chessboard_calibration(p, (640, 480), area, rng) for p in TILTED]
    )
    boxes = _exact_boxes(TILTED, PEOPLE)
    out = baseline.localize(boxes, calibrated, method="foot")
    assert np.linalg.norm(out - PEOPLE, axis=1).max() < 0.5


def test_wrong_method_or_shapes_raise() -> None:
    boxes = _exact_boxes(LEVEL, PEOPLE)
    with pytest.raises(MomlocError, match="method"):
        baseline.localize(boxes, LEVEL, method="magic")
    with pytest.raises(MomlocError, match="do not match"):
        baseline.localize(boxes, LEVEL[:2])
