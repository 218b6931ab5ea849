"""Joint floor fit: positions a biased model fused, corrected by the cameras' agreement."""

from __future__ import annotations

import numpy as np
import pytest

from common.errors import MomlocError
from models.geometry.floor_prior import FloorPrior
from models.geometry.joint_floor import _foot, fit_joint_floor, triangulate
from tests.models.test_floor_prior import SIZE, _boxes, _marks

SIZES = np.array([SIZE, SIZE], np.float64)


def _bent(world: np.ndarray) -> np.ndarray:
    """What a model fitted on a few marks gives between and beyond them: a smooth warp, up to
    about 0.3 m off at the room's far side (the error the joint fit exists to remove)."""
    x, y = world[:, 0], world[:, 1]
    return world + np.stack([0.06 * (y - 5.0) + 0.02 * (x - 5.0) ** 2, -0.05 * (x - 5.0)], 1)


def _moments(n: int, seed: int, noise: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """True positions [n, 2] of people walking the room and both cameras' boxes of them, their
    edges off by ``noise`` box heights."""
    rng = np.random.default_rng(seed)
    truth = rng.uniform(2.0, 8.0, (n, 2))
    boxes = _boxes(truth)
    height = (boxes[..., 3] - boxes[..., 1])[..., None]
    return truth, boxes + rng.normal(0.0, noise, boxes.shape) * height


def _error(prior: FloorPrior, seed: int = 9) -> float:
    truth, boxes = _moments(400, seed)
    xy, _ = prior.predict(boxes)
    return float(np.linalg.norm(xy - truth, axis=1).mean())


def test_positions_move_to_where_the_cameras_agree_and_the_refit_follows() -> None:
    marks_world, marks_boxes = _marks(grid=2)
    truth, boxes = _moments(600, seed=1)
    served = _bent(truth)  # the serving model's fused positions, its warp included
    joint = fit_joint_floor(marks_world, marks_boxes, served, boxes, SIZES)
    before = np.linalg.norm(served - truth, axis=1).mean()
    after = np.linalg.norm(joint.world - truth, axis=1).mean()
    assert before > 0.1 and after < 0.25 * before
    assert 590 <= joint.moments <= 600 and joint.moved_m > 0.05  # a few boxes cut at a border

    def refit(positions: np.ndarray) -> FloorPrior:
        world = np.concatenate([marks_world, positions])
        return FloorPrior.fit_arrays(world, np.concatenate([marks_boxes, boxes]), SIZES)

    one_step, jointly = _error(refit(served)), _error(refit(joint.world))
    marks_alone = _error(FloorPrior.fit_arrays(marks_world, marks_boxes, SIZES))
    assert jointly < 0.5 * one_step and jointly < 0.8 * marks_alone


def test_a_few_wrong_pairings_do_not_pull_the_maps() -> None:
    marks_world, marks_boxes = _marks(grid=2)
    truth, boxes = _moments(600, seed=2)
    wrong = np.arange(0, 600, 20)  # 5 %: camera 1's box is another person's, 2-4 m away
    boxes[wrong, 1] = _boxes(truth[wrong] + np.array([3.0, -2.0]))[:, 1]
    joint = fit_joint_floor(marks_world, marks_boxes, _bent(truth), boxes, SIZES)
    right = np.setdiff1d(np.arange(600), wrong)
    assert np.linalg.norm(joint.world[right] - truth[right], axis=1).mean() < 0.03


def test_moments_seen_by_one_camera_keep_their_position() -> None:
    marks_world, marks_boxes = _marks(grid=2)
    truth, boxes = _moments(200, seed=3)
    boxes[:50, 0] = np.nan
    served = _bent(truth)
    joint = fit_joint_floor(marks_world, marks_boxes, served, boxes, SIZES)
    np.testing.assert_array_equal(joint.world[:50], served[:50])
    assert 140 <= joint.moments <= 150 and not joint.placed[:50].any()
    assert joint.placed[50:].sum() == joint.moments
    boxes[:, 0] = np.nan
    with pytest.raises(MomlocError, match="two cameras"):
        fit_joint_floor(marks_world, marks_boxes, served, boxes, SIZES)


def test_the_start_fit_reads_the_chosen_moments_not_the_whole_store(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A full store holds ~100 000 labels: the one-camera start fit must not read them all in
    the daemon's background thread, only the marks and the moments the solve uses."""
    marks_world, marks_boxes = _marks(grid=2)
    truth, boxes = _moments(900, seed=4)
    rows: list[int] = []
    fit = FloorPrior.fit_arrays

    def counted(world: np.ndarray, *args: object, **kwargs: object) -> FloorPrior:
        rows.append(len(world))
        return fit(world, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(FloorPrior, "fit_arrays", staticmethod(counted))
    joint = fit_joint_floor(marks_world, marks_boxes, _bent(truth), boxes, SIZES, max_moments=200)
    assert rows == [len(marks_world) + 200] and joint.moments == 200
    assert np.linalg.norm(joint.world - truth, axis=1).mean() < 0.05  # all 900 placed


def test_a_moment_whose_solve_is_not_finite_keeps_its_position_and_is_not_placed() -> None:
    """``placed`` is what the training set trusts whole: a moment Gauss-Newton could not place
    (here a non-finite start) keeps its position and must not count as placed, even with two
    usable views."""
    marks_world, marks_boxes = _marks(grid=2)
    truth, boxes = _moments(300, seed=5)
    joint = fit_joint_floor(marks_world, marks_boxes, _bent(truth), boxes, SIZES)
    pixels, height, usable = _foot(boxes, SIZES)
    start = _bent(truth)
    start[:10] = np.nan
    world, placed = triangulate(joint.maps, pixels, height, usable, start)
    assert not placed[:10].any() and np.isnan(world[:10]).all()
    two = usable.sum(axis=1) >= 2
    assert two[:10].all() and (placed[10:] == two[10:]).all() and placed.sum() > 250
    assert np.linalg.norm(world[placed] - truth[placed], axis=1).mean() < 0.03
