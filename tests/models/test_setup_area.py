"""The set-up area: hull distances, camera regions, and a model that keeps people beyond its
labels beyond them (the encoder alone maps them into its training area)."""

import functools
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

from common.errors import MomlocError
from models.mom.runtime import MomRuntime
from models.mom.setup_area import SetupArea, distance_outside
from tests.models.mom_scene import make_dataset

SQUARE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])


def test_distance_to_a_convex_hull_is_zero_inside_and_euclidean_outside():
    area = SetupArea.fit(np.r_[SQUARE, [[1.0, 1.0]]], np.full((5, 1, 4), np.nan), margin_m=0.0)
    assert len(area.floor) == 4  # the inner point is not a vertex
    points = np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0], [3.0, 3.0], [np.nan, 0.0]])
    d = distance_outside(area.floor, points)
    np.testing.assert_allclose(d[:4], [0.0, 0.0, 1.0, np.sqrt(2.0)], atol=1e-9)
    assert np.isnan(d[4])


def test_contains_honours_the_margin_and_degenerate_hulls():
    area = SetupArea.fit(SQUARE, np.full((4, 1, 4), np.nan), margin_m=0.5)
    assert area.contains(
        np.array([[2.4, 1.0], [2.6, 1.0], [-0.49, -0.0], [np.nan, 1]])
    ).tolist() == [
        True,
        False,
        True,
        True,  # unknown is not evidence of elsewhere
    ]
    line = SetupArea.fit(np.array([[0.0, 0.0], [4.0, 0.0]]), np.full((2, 1, 4), np.nan))
    assert line.contains(np.array([[2.0, 0.4], [2.0, 0.6], [4.4, 0.0]])).tolist() == [
        True,
        False,
        True,
    ]


def test_camera_regions_judge_foot_points_and_box_heights():
    boxes = np.array(
        [[[100, 100, 140, 300]], [[300, 150, 340, 320]], [[200, 200, 230, 310]]], float
    )
    area = SetupArea.fit(np.array([[0, 0], [1, 0], [0, 1]], float), boxes)
    probe = np.array(
        [
            [[210, 120, 250, 290]],  # foot among the training feet, usual height
            [[600, 20, 620, 60]],  # far off in the image and tiny
            [[150, 50, 190, 300]],  # usual place, usual height
            [[150, 0, 190, 300 + 600]],  # twice the tallest box, foot far below
            [[np.nan] * 4],  # not seen: nothing says elsewhere
        ]
    )
    assert area.boxes_in_region(probe).tolist() == [True, False, True, False, True]
    with pytest.raises(MomlocError, match=r"set-up area: boxes"):
        area.boxes_in_region(np.zeros((1, 2, 4)))


def test_json_round_trip_and_malformed_entries():
    boxes = np.array(
        [[[100, 100, 140, 300]], [[300, 150, 340, 320]], [[200, 200, 230, 310]]], float
    )
    area = SetupArea.fit(np.array([[0, 0], [1, 0], [0, 1]], float), boxes)
    again = SetupArea.from_json(json.loads(json.dumps(area.to_json())))
    np.testing.assert_allclose(again.floor, area.floor)
    probe = np.array([[[210, 120, 250, 290]], [[600, 20, 620, 60]]], float)
    assert again.boxes_in_region(probe).tolist() == area.boxes_in_region(probe).tolist()
    with pytest.raises(MomlocError, match="setup_area"):
        SetupArea.from_json({"format": "setup-area-v1", "floor": [[0, 0]]})


@functools.cache
def _half_room_model() -> Path:
    """A dense model trained on people in the left half of a 6 m room only (x < 2.8 m)."""
    from models.mom.training.train import train_model

    data, _ = make_dataset(2400, cameras=2, seed=11)
    left = np.flatnonzero(data.world[:, 0] < 2.8)
    out = Path(tempfile.mkdtemp(prefix="mom-area-")) / "left"
    train_model(data.subset(left), out, epochs=25, seed=0, progress=False)
    return out


def test_people_beyond_the_labels_are_localized_by_geometry_and_reported_outside():
    runtime = MomRuntime.load(_half_room_model())
    assert runtime.setup_area is not None
    # served by the encoder alone inside the area, as the dense CMC model chose (issue 23)
    runtime.prior_weights = (0.0, 0.0, 0.0)
    data, _ = make_dataset(2400, cameras=2, seed=31)
    far = np.flatnonzero(data.world[:, 0] > 4.3)
    near = np.flatnonzero(data.world[:, 0] < 2.3)
    assert len(far) > 100 and len(near) > 100
    served = runtime.localize(data.boxes[far])
    encoder = runtime.encode(data.boxes[far])
    served_error = np.median(np.linalg.norm(served - data.world[far], axis=1))
    encoder_error = np.median(np.linalg.norm(encoder - data.world[far], axis=1))
    # the encoder pulls them into its training area; geometry keeps them where they are
    assert served_error < 0.5 * encoder_error
    assert runtime.inside(data.boxes[far], served).mean() < 0.1
    # inside the area nothing changes: the policy's answer, and reported inside
    inside_xy = runtime.localize(data.boxes[near])
    assert runtime.inside(data.boxes[near], inside_xy).mean() > 0.95


def test_models_without_an_area_count_everything_inside():
    runtime = MomRuntime.load(_half_room_model())
    runtime.setup_area = None
    data, _ = make_dataset(200, cameras=2, seed=32)
    assert runtime.inside(data.boxes, runtime.localize(data.boxes)).all()


def test_a_box_much_shorter_than_a_person_standing_there_is_out_of_region():
    """The height expected at a foot pixel is learned per camera: a fragment of an occluded
    body (half as tall) or two people in one box (twice as tall) stands where people stood in
    training, but is not what a person standing there looks like."""
    rng = np.random.default_rng(0)
    v = rng.uniform(200, 460, 200)  # foot rows: farther people stand higher in the image
    u = rng.uniform(100, 540, 200)
    h = (v - 120) * 1.4 * np.exp(rng.normal(0, 0.04, 200))  # perspective: taller when nearer
    boxes = np.stack([u - 0.2 * h, v - h, u + 0.2 * h, v], axis=1)[:, None]
    area = SetupArea.fit(np.c_[rng.uniform(0, 3, 200), rng.uniform(0, 3, 200)], boxes)
    region = area.cameras[0]
    assert region is not None and region.height_model is not None
    foot_v, foot_u = 400.0, 300.0
    person = (foot_v - 120) * 1.4
    probe = np.array(
        [
            [[foot_u - 20, foot_v - height, foot_u + 20, foot_v]]
            for height in (person, person / 2, person * 2)
        ]
    )
    assert area.boxes_in_region(probe).tolist() == [True, False, False]
    again = SetupArea.from_json(json.loads(json.dumps(area.to_json())))
    assert again.boxes_in_region(probe).tolist() == [True, False, False]


def test_the_feet_below_a_part_of_the_body_are_where_that_part_sits_on_a_standing_height():
    """A camera whose people look 0.8 (v - 100) px tall with their feet at row v: the feet
    under a box centre at row c solve c = v - 0.5 h(v), under a seated head's top at row r
    solve r = v - 0.64 h(v) (``foot_row`` with that share), whatever row the search starts at;
    a camera without a height model has no answer."""
    v = np.linspace(200, 460, 300)
    u = np.random.default_rng(0).uniform(100, 540, 300)  # columns independent of rows
    h = 0.8 * (v - 100)
    boxes = np.stack([u - 0.2 * h, v - h, u + 0.2 * h, v], axis=1)[:, None]
    area = SetupArea.fit(np.c_[np.linspace(0, 3, 300), np.linspace(0, 3, 300)], boxes)
    region = area.cameras[0]
    assert region is not None and region.height_model is not None
    feet = np.array([260.0, 330.0, 420.0])
    columns = np.full(3, 320.0)
    for share, start in ((0.5, None), (0.64, feet + 40.0)):
        rows = feet - share * 0.8 * (feet - 100)
        found = region.foot_row(columns, rows, share, start=rows if start is None else start)
        assert found is not None
        np.testing.assert_allclose(found, feet, atol=4.0)  # the log-quadratic fit of h
        expected = region.expected_height(np.stack([columns, found], 1))
        assert expected is not None
        np.testing.assert_allclose(found - rows, share * expected, atol=0.5)
    small = SetupArea.fit(np.zeros((3, 2)), boxes[:3]).cameras[0]
    assert small is not None and small.foot_row(columns, feet, 0.5, start=feet) is None
