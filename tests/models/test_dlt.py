"""The one DLT fit: a known 3×4 camera matrix and a known 3×3 homography come back exactly."""

from __future__ import annotations

import numpy as np
import pytest

from common.errors import MomlocError
from models.geometry.dlt import fit_dlt


def _unit(m: np.ndarray) -> np.ndarray:
    m = m / np.linalg.norm(m)
    return m * np.sign(m[-1, -1])


def _map(m: np.ndarray, points: np.ndarray) -> np.ndarray:
    h = np.c_[points, np.ones(len(points))] @ m.T
    return h[:, :2] / h[:, 2:]


def test_recovers_a_camera_matrix_from_3d_points() -> None:
    k = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    angle = np.radians(25)
    r = np.array([[1, 0, 0], [0, np.cos(angle), -np.sin(angle)], [0, np.sin(angle), np.cos(angle)]])
    p = k @ np.c_[r, [0.2, -0.4, 6.0]]
    world = np.random.default_rng(0).uniform([-2, -2, 0], [2, 2, 1.8], (20, 3))
    fitted = fit_dlt(world, _map(p, world))
    assert fitted.shape == (3, 4)
    np.testing.assert_allclose(_unit(fitted), _unit(p), atol=1e-9)


def test_recovers_a_homography_from_2d_points() -> None:
    h = np.array([[80.0, 12.0, 300.0], [-4.0, 30.0, 420.0], [0.01, 0.12, 1.0]])
    floor = np.random.default_rng(1).uniform(0, 8, (12, 2))
    fitted = fit_dlt(floor, _map(h, floor))
    assert fitted.shape == (3, 3)
    np.testing.assert_allclose(_unit(fitted), _unit(h), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(fitted), 1.0)


def test_minimal_pairs_fix_the_map_exactly() -> None:
    # 4 pairs give 8 equations for 9 unknowns: the answer is the null vector the SVD must hold
    # (a thin SVD of the 8 x 9 system drops it; that fit was metres off).
    h = np.array([[80.0, 12.0, 300.0], [-4.0, 30.0, 420.0], [0.01, 0.12, 1.0]])
    floor = np.array([[0.0, 0.0], [4.0, 0.5], [3.5, 5.0], [0.5, 4.0]])
    np.testing.assert_allclose(_unit(fit_dlt(floor, _map(h, floor))), _unit(h), atol=1e-9)
    square = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]])
    with pytest.raises(MomlocError, match="degenerate"):  # three of four on a line
        fit_dlt(np.r_[square, [[2.0, 0.0]]], np.r_[square, [[1.0, 0.0]]] * 50)


def test_refuses_too_few_or_degenerate_points() -> None:
    floor = np.random.default_rng(2).uniform(0, 8, (12, 2))
    with pytest.raises(MomlocError, match=r"^marks: need >= 4 matched points, got 3"):
        fit_dlt(floor[:3], floor[:3], what="marks")
    line = np.c_[floor[:, 0], 2 * floor[:, 0] + 1]
    with pytest.raises(MomlocError, match="degenerate"):
        fit_dlt(line, floor)
    flat = np.c_[floor, np.zeros(12)]  # coplanar world points fix no camera matrix
    with pytest.raises(MomlocError, match="degenerate"):
        fit_dlt(flat, floor)
    with pytest.raises(MomlocError, match=r"\[N, 2\] or \[N, 3\]"):
        fit_dlt(np.zeros((8, 4)), floor[:8])
