"""Postures and furniture in the simulator: seated, crouching and lying bodies, legs hidden by a
table in the boxes and in the drawn frames, scripted people in the furnished presets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from common.errors import MomlocError
from models.simulate import PRESETS, Scene, get_config
from models.simulate.furniture import Occluders, table
from models.simulate.postures import CODES, LYING, SITTING
from models.simulate.script import ScriptedWalker, Segment
from models.simulate.skeleton import MID_HIP, P, body_points

ONE = np.zeros(1)


def _pose(posture: str, height: float = 1.75) -> np.ndarray:
    code = np.array([CODES[posture]])
    return body_points(np.zeros((1, 2)), ONE, ONE, ONE * 0, np.array([height]), code, ONE + 1)[0]


def test_held_poses_have_the_shape_of_the_posture() -> None:
    standing, sitting = _pose("standing"), _pose("sitting")
    crouching, lying = _pose("crouching"), _pose("lying")
    top = P["crown"]
    assert standing[top, 2] == pytest.approx(1.75 * 0.42 + 0.92, abs=0.2)
    # seated: head ~0.45 m lower, hips on a seat ~0.44 m up, feet ahead of the hips
    assert 0.35 < standing[top, 2] - sitting[top, 2] < 0.6
    assert 0.38 < sitting[MID_HIP, 2] < 0.5
    assert sitting[P["left_ankle"], 0] > 0.4
    assert crouching[top, 2] < 1.15 and crouching[MID_HIP, 2] < 0.45
    assert lying[:, 2].max() < 0.35  # nothing higher than a chest on the floor
    assert lying[P["nose"], 0] > 0.6 and lying[P["left_ankle"], 0] < -0.8  # head along heading
    # the mid-hip stays over the label point in every posture
    for pose in (standing, sitting, lying):
        assert np.linalg.norm(pose[MID_HIP, :2]) < 0.1


def test_scripted_sitting_ramps_in_and_out() -> None:
    seat = (2.0, 2.0)
    script = [
        Segment((1.0, 2.0), seat, 1.0),
        Segment(seat, seat, 10.0, "sitting", heading=0.0, ramp_s=2.0),
        Segment(seat, (3.0, 2.0), 1.0),
    ]
    walker = ScriptedWalker(script, 10.0, np.random.default_rng(0))
    states = walker.states(0, 130)
    code, weight = states.postures()
    assert code[5, 0] == 0 and code[20, 0] == SITTING
    assert weight[11, 0] < 0.2 and weight[40, 0] == 1.0 and weight[105, 0] < 0.5
    assert np.allclose(states.heading[40:100, 0], 0.0)
    assert np.abs(states.position[40:100, 0] - seat).max() < 0.02  # barely moves
    with pytest.raises(MomlocError, match="dancing"):
        Segment(seat, seat, 1.0, "dancing")


def test_a_table_hides_the_legs_in_boxes_and_joints() -> None:
    """Someone seated behind a table: the box ends above the table top, shins are occluded."""
    base = get_config("living-room")
    seat = (2.5, 3.0)
    config = dataclasses.replace(
        base, people=0, furniture=table(1.8, 2.0, 3.2, 2.5, top=0.74),
        scripts=((Segment(seat, seat, 60.0, "sitting", heading=-np.pi / 2),),),
    )  # fmt: skip
    plain = dataclasses.replace(config, furniture=())
    hidden = Scene(config, seed=1)._compute_block(0)
    open_view = Scene(plain, seed=1)._compute_block(0)
    frame = 40
    for k in range(2):
        covered = hidden["true_boxes"][frame, 0, k]
        full = open_view["true_boxes"][frame, 0, k]
        assert covered[3] < full[3] - 10  # the bottom edge moved up: the feet are hidden
        assert covered[1] == pytest.approx(full[1])  # the head is not
    occluders = Occluders(config.furniture)
    points = body_points(
        np.array([[seat]]), np.array([[-np.pi / 2]]), ONE[None], ONE[None] * 0,
        np.array([1.75]), np.array([[SITTING]]), ONE[None],
    )  # fmt: skip
    hid = occluders.hidden(points, Scene(config, seed=1).cameras)[0, :, 0]
    assert hid[:, P["left_ankle"]].all() and not hid[:, P["nose"]].any()


def test_a_table_hides_the_legs_in_the_drawn_frame() -> None:
    pytest.importorskip("cv2")
    seat = (2.5, 3.0)
    config = dataclasses.replace(
        get_config("living-room"), people=0, furniture=table(1.8, 2.0, 3.2, 2.5, top=0.74),
        scripts=((Segment(seat, seat, 60.0, "sitting", heading=-np.pi / 2),),),
    )  # fmt: skip
    scene = Scene(config, seed=1)
    image = scene.render(40, 0)
    assert scene._renderer is not None
    background = scene._renderer.background(scene.cameras_at(40)[0])
    changed = np.abs(image.astype(int) - background.astype(int)).sum(-1) > 30
    visible = scene.observe(40).true_boxes[0, 0]
    x0, y0, x1, y1 = np.round(visible).astype(int)
    rows = np.flatnonzero(changed[:, x0:x1].any(1))
    assert rows.min() < y0 + 6  # the head is drawn
    assert rows.max() < y1 + 8  # nothing is drawn below the visible box: the table covers it


def test_lying_person_box_is_wide_and_flat() -> None:
    spot = (2.5, 2.0)
    config = dataclasses.replace(
        get_config("living-room"), people=0,
        scripts=((Segment(spot, spot, 60.0, "lying", heading=0.0, ramp_s=0.8),),),
    )  # fmt: skip
    obs = Scene(config, seed=2).observe(30)
    boxes = obs.true_boxes[0]
    width, height = boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]
    assert np.nanmax(width / height) > 1.2  # seen from 2 m up at 45°: foreshortened
    assert obs.world[0, :2] == pytest.approx(spot, abs=0.02)


@pytest.mark.parametrize("name", ["lounge", "office-desks", "demo-lounge"])
def test_furnished_presets_seat_their_people(name: str) -> None:
    config = PRESETS[name]
    scene = Scene(config, seed=0)
    obs = scene.observe(200)
    assert len(obs.track) == config.people + len(config.scripts)
    code, _ = scene.walkers.states(200, 201).postures()
    assert (code[0] == SITTING).sum() >= 1
    assert np.isfinite(obs.true_boxes).all(-1).any()
    assert LYING not in code
