"""Floor prior: homography fit, foot pixel → floor point, fusion with missing views, degeneracy."""

from __future__ import annotations

import json

import numpy as np
import pytest

from common.errors import MomlocError
from models.geometry.dlt import fit_dlt
from models.geometry.floor_prior import FloorPrior
from models.geometry.homography import (
    apply_homography,
    fit_homography,
    homography_jacobian,
)

SIZE = (640, 480)
FOCAL = 500.0


def _camera(eye: tuple[float, float, float], target=(5.0, 5.0, 0.9)) -> np.ndarray:
    """A pinhole P [3, 4] at ``eye`` looking at ``target`` (z up, image v down)."""
    eye_v, forward = np.asarray(eye), np.asarray(target) - np.asarray(eye)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rot = np.stack([right, down, forward])
    k = np.array([[FOCAL, 0, SIZE[0] / 2], [0, FOCAL, SIZE[1] / 2], [0, 0, 1]])
    return k @ np.concatenate([rot, -(rot @ eye_v)[:, None]], axis=1)


CAMERAS = (_camera((0.0, 0.0, 2.3)), _camera((10.0, 0.0, 2.4)))


def _project(p: np.ndarray, points: np.ndarray) -> np.ndarray:
    h = np.concatenate([points, np.ones((len(points), 1))], axis=1) @ p.T
    return h[:, :2] / h[:, 2:3]


def _boxes(world: np.ndarray, cameras=CAMERAS, height: float = 1.7) -> np.ndarray:
    """Person boxes [N, K, 4] of upright people standing at ``world`` [N, 2] (exact geometry)."""
    out = []
    for p in cameras:
        foot = _project(p, np.c_[world, np.zeros(len(world))])
        head = _project(p, np.c_[world, np.full(len(world), height)])
        half = 0.2 * (foot[:, 1] - head[:, 1])
        out.append(np.stack([foot[:, 0] - half, head[:, 1], foot[:, 0] + half, foot[:, 1]], 1))
    return np.stack(out, axis=1)


def _marks(
    grid: int = 3, per_mark: int = 20, seed: int = 0, sway: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """Rows at a grid of marks in the middle of the room, the person swaying (std ``sway`` m)."""
    rng = np.random.default_rng(seed)
    centres = (np.arange(grid) + 0.5) * 6.0 / grid + 2.0
    marks = np.stack(np.meshgrid(centres, centres), axis=-1).reshape(-1, 2)
    world = np.repeat(marks, per_mark, axis=0)
    actual = world + rng.normal(0.0, sway, world.shape)
    return world, _boxes(actual)


def test_homography_fit_recovers_a_known_map_from_exact_points():
    truth = np.array([[1.2, 0.1, -30.0], [0.05, 0.9, 12.0], [2e-4, 1e-3, 1.0]])
    src = np.random.default_rng(1).uniform([0, 0], [640, 480], (30, 2))
    dst = apply_homography(truth, src)
    for h in (fit_dlt(src, dst), fit_homography(src, dst)):
        h = h / h[2, 2]
        np.testing.assert_allclose(h, truth / truth[2, 2], rtol=1e-6, atol=1e-9)
        probe = np.array([[100.0, 400.0], [600.0, 50.0]])
        np.testing.assert_allclose(apply_homography(h, probe), apply_homography(truth, probe))


def test_homography_fit_ignores_a_few_gross_outliers():
    truth = np.array([[0.01, 0.002, -3.0], [0.001, 0.02, -4.0], [1e-5, 2e-4, 1.0]])
    rng = np.random.default_rng(2)
    src = rng.uniform([0, 0], [640, 480], (200, 2))
    dst = apply_homography(truth, src) + rng.normal(0, 0.01, (200, 2))
    dst[:10] += 3.0  # ten rows labelled three metres off (a second person)
    probe = rng.uniform([0, 0], [640, 480], (50, 2))
    fitted = apply_homography(fit_homography(src, dst), probe)
    err = np.linalg.norm(fitted - apply_homography(truth, probe), axis=1)
    assert err.max() < 0.05


def test_jacobian_matches_finite_differences():
    h = np.array([[1.2, 0.1, -30.0], [0.05, 0.9, 12.0], [2e-4, 1e-3, 1.0]])
    point = np.array([[300.0, 200.0]])
    eps = 1e-4
    steps = np.eye(2) * eps
    numeric = np.stack(
        [apply_homography(h, point + d) - apply_homography(h, point - d) for d in steps], axis=-1
    ) / (2 * eps)
    np.testing.assert_allclose(homography_jacobian(h, point), numeric, rtol=1e-6)


def test_prior_maps_a_foot_pixel_to_its_floor_point_outside_the_marks():
    world, boxes = _marks(sway=0.0)
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="foot")
    assert prior.cameras[0] is not None and prior.cameras[0].marks == 9
    # Far outside the 2-8 m square of the marks: geometry, not interpolation.
    probe = np.array([[1.0, 9.0], [9.0, 9.5], [5.0, 5.0], [8.5, 1.5]])
    xy, std = prior.predict(_boxes(probe))
    np.testing.assert_allclose(xy, probe, atol=1e-3)
    assert (std > 0).all() and (std < 0.5).all()
    for k in range(2):  # each camera alone maps its own foot pixel to the same floor point
        alone = _boxes(probe)
        alone[:, 1 - k] = np.nan
        np.testing.assert_allclose(prior.predict(alone)[0], probe, atol=1e-3)


def test_swaying_on_the_marks_costs_centimetres_not_decimetres():
    world, boxes = _marks(sway=0.05)
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="foot")
    inside = np.array([[3.0, 3.0], [5.0, 5.0], [7.0, 6.0]])
    np.testing.assert_allclose(prior.predict(_boxes(inside))[0], inside, atol=0.03)
    outside = np.array([[1.0, 9.0], [9.0, 9.5], [8.5, 1.5]])
    np.testing.assert_allclose(prior.predict(_boxes(outside))[0], outside, atol=0.12)


def test_a_mark_where_a_camera_saw_only_furniture_is_left_out_of_its_map():
    """At one mark camera 1 hardly saw the person and a lasting false box was recorded instead:
    that mark's pixel is off the plane map of the other eight and must not bend it."""
    world, boxes = _marks(sway=0.02)
    at_mark = (world == world[0]).all(axis=1)
    boxes[at_mark, 1] = [420.0, 250.0, 470.0, 380.0]  # a coat on a chair, every frame
    probe = np.array([[1.0, 9.0], [9.0, 9.5], [5.0, 5.0], [8.5, 1.5]])
    seen_by_1 = _boxes(probe)
    seen_by_1[:, 0] = np.nan
    fitted = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="foot")
    np.testing.assert_allclose(fitted.predict(seen_by_1)[0], probe, atol=0.1)


def test_fusion_uses_the_views_that_see_the_person():
    world, boxes = _marks()
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="both")
    probe = np.array([[3.0, 7.0], [6.0, 4.0]])
    full = _boxes(probe)
    one = full.copy()
    one[0, 1] = np.nan  # row 0: camera 1 misses the person
    one[1, 0] = np.nan  # row 1: camera 0 misses the person
    xy_full, std_full = prior.predict(full)
    xy_one, std_one = prior.predict(one)
    np.testing.assert_allclose(xy_one, probe, atol=0.05)
    np.testing.assert_allclose(xy_full, probe, atol=0.05)
    assert (std_one > std_full).all()  # a single view knows less than two
    _, info = prior.views(one)
    assert np.all(info[0, 1] == 0) and np.all(info[1, 0] == 0)
    unseen = np.full((1, 2, 4), np.nan)
    xy_none, std_none = prior.predict(unseen)
    assert np.isnan(xy_none).all() and np.isinf(std_none).all()


def test_fusion_weighs_views_by_their_error_model():
    """Noisy boxes: fused error beats each camera alone (triangulation-like behaviour)."""
    world, boxes = _marks(per_mark=60, seed=3)
    rng = np.random.default_rng(4)
    noisy = boxes + rng.normal(0, 2.0, boxes.shape)
    prior = FloorPrior.fit_arrays(world, noisy, np.array([SIZE, SIZE]))
    probe = rng.uniform(2.0, 8.0, (400, 2))
    test = _boxes(probe) + rng.normal(0, 2.0, (400, 2, 4))
    fused = np.linalg.norm(prior.predict(test)[0] - probe, axis=1).mean()
    for k in range(2):
        alone = test.copy()
        alone[:, 1 - k] = np.nan
        single = np.linalg.norm(prior.predict(alone)[0] - probe, axis=1).mean()
        assert fused < 0.8 * single


def test_camera_with_too_few_marks_gets_no_prior():
    world, boxes = _marks()
    sees = np.isin(np.arange(len(world)) // 20, [0, 1, 2])  # camera 1: only the first 3 marks
    boxes[~sees, 1] = np.nan
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]))
    assert prior.cameras[0] is not None and prior.cameras[1] is None
    assert any("camera 1" in note and "3 distinct" in note for note in prior.notes)
    probe = np.array([[4.0, 6.0]])
    xy, _ = prior.predict(_boxes(probe))
    np.testing.assert_allclose(xy, probe, atol=0.03)


def test_camera_whose_boxes_never_move_gets_no_prior():
    world, boxes = _marks()
    boxes[:, 1] = [300.0, 100.0, 340.0, 300.0]  # a frozen feed: the same box on every mark
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="foot")
    assert prior.cameras[0] is not None and prior.cameras[1] is None
    assert any("camera 1" in note and "degenerate" in note for note in prior.notes)


def test_collinear_marks_raise_a_readable_error():
    xs = np.repeat(np.linspace(2.0, 8.0, 5), 10)
    world = np.stack([xs, np.full_like(xs, 5.0)], axis=1)
    with pytest.raises(MomlocError, match=r"no camera.*line"):
        FloorPrior.fit_arrays(world, _boxes(world), np.array([SIZE, SIZE]))
    # Three marks on a line and one off it: still no homography (all but one on a line).
    world = np.repeat([[2.0, 2.0], [4.0, 2.0], [6.0, 2.0], [4.0, 6.0]], 10, axis=0)
    with pytest.raises(MomlocError, match="all floor positions but one"):
        FloorPrior.fit_arrays(world, _boxes(world), np.array([SIZE, SIZE]))


def test_json_round_trip_gives_the_same_predictions():
    world, boxes = _marks()
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="both")
    again = FloorPrior.from_json(json.loads(json.dumps(prior.to_json())))
    probe = _boxes(np.array([[1.5, 8.0], [7.0, 3.0]]))
    for a, b in zip(prior.predict(probe), again.predict(probe), strict=True):
        np.testing.assert_allclose(a, b)
    with pytest.raises(MomlocError, match="floor prior"):
        FloorPrior.from_json({"format": "floor-prior-v1", "cameras": [{"points": ["foot"]}]})


def test_reprojection_finds_the_foot_pixel_and_flags_a_moved_camera():
    world, boxes = _marks(sway=0.0)
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]))
    probe = np.array([[1.5, 8.0], [7.0, 3.0]])
    seen = _boxes(probe)
    foot = np.stack([(seen[..., 0] + seen[..., 2]) / 2, seen[..., 3]], axis=-1)
    np.testing.assert_allclose(prior.reproject(probe), foot, atol=1e-3)
    assert prior.reprojection_error(seen, probe).max() < 1e-3
    bumped = seen.copy()
    bumped[:, 1] += [25.0, 0.0, 25.0, 0.0]  # camera 1 turned: everything 25 px to the right
    err = prior.reprojection_error(bumped, probe)
    assert err[:, 0].max() < 1e-3 and np.allclose(err[:, 1], 25.0, atol=1e-3)


def _ankles(world: np.ndarray, confidence: float = 0.9) -> np.ndarray:
    """COCO-17 keypoints [N, K, 17, 3]: only the ankles (8 cm above the floor) are known."""
    out = np.full((len(world), len(CAMERAS), 17, 3), np.nan)
    for k, p in enumerate(CAMERAS):
        ankle = _project(p, np.c_[world, np.full(len(world), 0.08)])
        out[:, k, 15:17, :2] = ankle[:, None]
        out[:, k, 15:17, 2] = confidence
    return out


def test_ankle_keypoints_give_their_own_floor_map():
    world, boxes = _marks(sway=0.0)
    size = np.array([SIZE, SIZE])
    with pytest.raises(MomlocError, match="keypoints"):
        FloorPrior.fit_arrays(world, boxes, size, points="ankle")
    prior = FloorPrior.fit_arrays(world, boxes, size, keypoints=_ankles(world), points="ankle")
    probe = np.array([[1.5, 8.0], [7.0, 3.0]])
    xy, _ = prior.predict(_boxes(probe), _ankles(probe))
    np.testing.assert_allclose(xy, probe, atol=1e-3)
    unsure, std = prior.predict(_boxes(probe), _ankles(probe, confidence=0.2))
    assert np.isnan(unsure).all() and np.isinf(std).all()  # low-confidence ankles are unseen
    everything = FloorPrior.fit_arrays(world, boxes, size, keypoints=_ankles(world), points="all")
    first = everything.cameras[0]
    assert first is not None and first.points == ("foot", "centre", "ankle")
    xy, _ = everything.predict(_boxes(probe))  # served without keypoints: boxes only
    np.testing.assert_allclose(xy, probe, atol=0.02)


def test_wrong_box_shape_is_a_user_error():
    world, boxes = _marks()
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]))
    with pytest.raises(MomlocError, match=r"\[B, 2, 4\]"):
        prior.predict(np.zeros((3, 3, 4)))


def test_single_view_covariance_is_long_along_the_line_of_sight():
    """One camera: the covariance's long axis points from the camera to the person, and its
    size is the one ``predict`` reports; two cameras shrink it in every direction."""
    world, boxes = _marks(per_mark=60, seed=3)
    noisy = boxes + np.random.default_rng(5).normal(0, 2.0, boxes.shape)
    prior = FloorPrior.fit_arrays(world, noisy, np.array([SIZE, SIZE]))
    probe = np.array([[6.0, 6.0], [3.0, 7.0]])
    one = _boxes(probe)
    one[:, 1] = np.nan  # camera 0 (at the origin) only
    _, cov = prior.predict_covariance(one)
    _, std = prior.predict(one)
    np.testing.assert_allclose(np.sqrt(np.trace(cov, axis1=1, axis2=2) / 2), std)
    for p, c in zip(probe, cov, strict=True):
        values, vectors = np.linalg.eigh(c)
        sight = p / np.linalg.norm(p)  # camera 0 stands at (0, 0)
        assert abs(vectors[:, 1] @ sight) > 0.95
        assert values[1] > 4 * values[0]
    _, both = prior.predict_covariance(_boxes(probe))
    assert (np.linalg.eigvalsh(cov - both) > 0).all()
    xy_none, cov_none = prior.predict_covariance(np.full((1, 2, 4), np.nan))
    assert np.isnan(xy_none).all() and np.isnan(cov_none).all()


def test_marks_whose_boxes_are_not_the_person_are_left_out_of_the_fit():
    """The default 3x3 grid of marks; at two of them camera 0 reports something that is
    not the person standing there: a static false positive (a coat on a chair) while the
    person is out of its view, and the person with the feet cut off by the image border (the
    box's noisy bottom edge ends a few pixels inside it, so it looks whole). One such mark
    used to send the map a metre off; a consensus over the marks leaves both out."""
    world, boxes = _marks(grid=3, sway=0.0)
    marks = np.unique(world, axis=0)
    wrong = [0, 8]
    fakes = ([100.0, 200.0, 140.0, 420.0], [300.0, 250.0, 330.0, 478.0])
    for m, fake in zip(wrong, fakes, strict=True):
        rows = np.all(world == marks[m], axis=1)
        boxes[rows, 0] = fake
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="foot")
    probe = np.array([[2.5, 3.0], [4.0, 6.0], [5.0, 5.0], [7.5, 7.0]])
    alone = _boxes(probe)
    alone[:, 1] = np.nan
    np.testing.assert_allclose(prior.predict(alone)[0], probe, atol=0.01)


def test_one_static_false_box_at_several_marks_is_not_the_person_at_any():
    """Camera 0 of the default 3x3 grid sees the person at only five marks: at three far ones
    it reports the same static false positive (one place, one size: impossible for a person at
    three floor points), at a fourth the feet are cut. Four wrong points of nine can outvote
    five right ones in a consensus (they fit a near-degenerate map), so boxes repeated at
    marks over a metre apart are left out first."""
    world, boxes = _marks(grid=3, sway=0.0)
    marks = np.unique(world, axis=0)
    static = [290.0, 200.0, 330.0, 380.0]
    for m, fake in ((0, static), (6, static), (8, static), (2, [300.0, 250.0, 330.0, 478.0])):
        boxes[np.all(world == marks[m], axis=1), 0] = fake
    prior = FloorPrior.fit_arrays(world, boxes, np.array([SIZE, SIZE]), points="foot")
    probe = np.array([[2.5, 3.0], [4.0, 6.0], [5.0, 5.0], [7.5, 7.0]])
    alone = _boxes(probe)
    alone[:, 1] = np.nan
    np.testing.assert_allclose(prior.predict(alone)[0], probe, atol=0.01)
