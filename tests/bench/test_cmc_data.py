"""The CMC bench's evaluation pairing (bench/real/cmc_data.py) on a made-up camera: a box where the
person stands is theirs, a box elsewhere is nobody's, and the foot point inverts the floor
projection."""

from __future__ import annotations

import numpy as np

from bench.real.cmc_data import expected_boxes, floor_points, in_area, pair_boxes, project


def camera() -> np.ndarray:
    """A 1920 x 1024 camera 2.2 m up at (0, 0), looking along +x, tilted down a little."""
    f, cx, cy = 1000.0, 960.0, 512.0
    tilt = np.deg2rad(15)
    forward = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    right = np.array([0.0, -1.0, 0.0])
    down = np.cross(forward, right)
    rotation = np.stack([right, down, forward])
    centre = np.array([0.0, 0.0, 2.2])
    k = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1]])
    return k @ np.c_[rotation, -rotation @ centre]


def test_foot_point_inverts_the_floor_projection() -> None:
    p = camera()
    floor = np.array([[3.0, 0.5], [5.0, -1.0]])
    pixels, front = project(p, np.c_[floor, np.zeros(2)])
    assert front.all()
    boxes = np.c_[pixels[:, 0] - 30, pixels[:, 1] - 300, pixels[:, 0] + 30, pixels[:, 1]]
    np.testing.assert_allclose(floor_points(p, boxes), floor, atol=1e-9)


def test_pairing_takes_the_persons_box_and_leaves_the_stranger() -> None:
    p = camera()
    world, z_c = np.array([[3.0, 0.5], [4.0, -1.0]]), np.array([0.85, 0.8])
    expected = expected_boxes(p, world, z_c)
    assert np.isfinite(expected).all()
    stranger = [1700.0, 100.0, 1800.0, 400.0]
    boxes = np.array([stranger, expected[1] + [8, -5, 8, 10], expected[0] + [-10, 6, 4, -3]])
    np.testing.assert_array_equal(pair_boxes(p, world, z_c, boxes), [-1, 1, 0])
    behind = expected_boxes(p, np.array([[-3.0, 0.0]]), np.array([0.85]))
    assert np.isnan(behind).all()


def test_area() -> None:
    np.testing.assert_array_equal(
        in_area(np.array([[2.5, 1.0], [1.0, 1.0], [6.3, 3.41]])), [1, 0, 1]
    )
