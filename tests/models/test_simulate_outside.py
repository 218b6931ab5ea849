"""People outside the set-up area: where they walk, how they are reported and kept apart."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from common.errors import MomlocError
from models.simulate import PRESETS, Scene, get_config, simulate
from models.simulate.outside import strips

AREA = (3.0, 7.0, 0.0, 10.0)  # a 4 m wide set-up area across a 10 x 10 m room


def _config(outside: int, area: tuple[float, float, float, float] | None = AREA, band=0.0):
    return dataclasses.replace(
        PRESETS["indoor-4cam"], area=area, outside_people=outside, outside_band=band
    )


def test_default_presets_have_nobody_outside_and_empty_outside_arrays() -> None:
    for name in ("indoor-2cam", "indoor-4cam", "outdoor-6cam", "living-room", "office-3cam"):
        assert PRESETS[name].outside_people == 0 and PRESETS[name].area is None
    obs = Scene(PRESETS["indoor-2cam"], seed=3).observe(5)
    assert obs.outside_world.shape == (0, 2)
    assert obs.outside_boxes.shape == (0, 2, 4)
    assert obs.outside_keypoints.shape == (0, 2, 17, 3)
    assert not obs.reported_outside(0).any()


def test_area_keeps_labelled_people_inside_and_outside_people_out() -> None:
    scene = Scene(_config(6), seed=1)
    world, outside = [], []
    for block in range(4):
        data = scene.observe_block(block)
        world.append(data["world"].reshape(-1, 2))
        outside.append(data["outside_world"].reshape(-1, 2))
    inner, outer = np.concatenate(world), np.concatenate(outside)
    assert inner.shape[1] == 2 and outer.shape[0] == 4 * 64 * 6
    assert ((inner[:, 0] >= 3.0) & (inner[:, 0] <= 7.0)).all()
    assert ((outer[:, 0] < 3.0) | (outer[:, 0] > 7.0)).all()
    assert (outer >= 0).all() and (outer <= 10).all()  # no band: inside the room
    assert (outer[:, 0] < 3.0).any() and (outer[:, 0] > 7.0).any()  # both strips used


def test_outside_people_are_reported_with_noise_and_flagged() -> None:
    scene = Scene(_config(4), seed=2)
    seen = 0
    for i in range(0, 120, 7):
        obs = scene.observe(i)
        assert obs.track.tolist() == [0, 1, 2] and obs.world.shape == (3, 2)
        for k in range(4):
            boxes, points = obs.reported(k)
            flags = obs.reported_outside(k)
            assert flags.shape == (len(boxes),) and len(points) == len(boxes)
            found = obs.outside_boxes[:, k]
            found = found[np.isfinite(found).all(-1)]
            np.testing.assert_array_equal(boxes[flags], found)
            seen += len(found)
    assert seen > 50
    # Same detector noise as everyone: found boxes differ from the tight true ones.
    data = scene.observe_block(0)
    noisy, true = data["outside_boxes"], data["outside_true_boxes"]
    both = np.isfinite(noisy).all(-1) & np.isfinite(true).all(-1)
    assert np.abs(noisy[both] - true[both]).mean() > 1.0


def test_outside_people_are_deterministic_and_not_in_the_dataset() -> None:
    a = Scene(_config(3), seed=5).observe(70)
    b = Scene(_config(3), seed=5).observe(70)
    np.testing.assert_array_equal(a.outside_world, b.outside_world)
    np.testing.assert_array_equal(a.outside_boxes, b.outside_boxes)
    c = Scene(_config(3), seed=6).observe(70)
    assert not np.allclose(a.outside_world, c.outside_world)
    result = simulate(_config(3), frames=64, seed=5)
    assert set(result.dataset.track.tolist()) <= {0, 1, 2}
    x = result.dataset.world[:, 0]
    assert ((x >= 3.0) & (x <= 7.0)).all()


def test_an_area_covering_the_room_draws_what_no_area_draws() -> None:
    """The area only moves the labelled walkers: the whole room as area changes nothing."""
    plain = Scene(PRESETS["office-3cam"], seed=4).observe(100)
    whole = dataclasses.replace(PRESETS["office-3cam"], area=(0.0, 8.0, 0.0, 6.0))
    same = Scene(whole, seed=4).observe(100)
    for key in ("world", "boxes", "keypoints", "false_boxes"):
        np.testing.assert_array_equal(getattr(plain, key), getattr(same, key))


def test_band_beyond_the_room_when_the_area_is_the_whole_room() -> None:
    config = get_config("indoor-2cam", outside_people=5)
    with pytest.raises(MomlocError, match="no floor outside"):
        Scene(config, seed=0)
    scene = Scene(dataclasses.replace(config, outside_band=2.0), seed=0)
    where = scene.observe_block(0)["outside_world"].reshape(-1, 2)
    off_room = (where < 0).any(-1) | (where > 10).any(-1)
    assert off_room.all() and (where > -2).all() and (where < 12).all()


def test_strips_and_bad_areas() -> None:
    assert strips((10.0, 10.0), AREA, 0.0) == [(0.0, 3.0, 0.0, 10.0), (7.0, 10.0, 0.0, 10.0)]
    assert len(strips((10.0, 10.0), (2.0, 8.0, 2.0, 8.0), 0.0)) == 4
    # a region of its own: only its part outside the area
    assert strips((10.0, 10.0), AREA, 0.0, (1.0, 5.0, 2.0, 8.0)) == [(1.0, 3.0, 2.0, 8.0)]
    assert strips((10.0, 10.0), (2.0, 8.0, 2.0, 8.0), 0.0, (3.0, 5.0, 0.0, 10.0)) == [
        (3.0, 5.0, 0.0, 2.0),
        (3.0, 5.0, 8.0, 10.0),
    ]
    with pytest.raises(MomlocError, match="area"):
        _config(1, area=(3.0, 12.0, 0.0, 10.0))
    with pytest.raises(MomlocError, match="outside"):
        _config(-1)


def test_rendered_frames_show_outside_people() -> None:
    config = dataclasses.replace(_config(4), people=1)
    scene = Scene(config, seed=3)
    assert scene.body_points(0).shape[0] == 5
    image = scene.render(0, 0)
    assert image.shape == (480, 640, 3)


def test_cmc_room_preset_copies_the_real_room() -> None:
    config = PRESETS["cmc-room"]
    assert config.room == (7.67, 3.41) and config.fps == 4.0 and config.num_cameras == 4
    assert config.area == (2.03, 6.3, 0.0, 3.41) and config.outside_people > 0
    scene = Scene(config, seed=0)
    outside = scene.observe_block(0)["outside_world"].reshape(-1, 2)
    assert (outside[:, 0] >= 0.25).all() and (outside[:, 0] <= 2.03).all()
    assert scene.image_sizes.tolist() == [[1920, 1024]] * 4
    for camera in scene.cameras:  # every camera sees the middle of the set-up area
        pixels, front = camera.project(np.array([4.0, 1.7, 0.9]))
        assert front and 0 < pixels[0] < 1920 and 0 < pixels[1] < 1024
    seen = np.isfinite(scene.observe_block(0)["true_boxes"]).all(-1)  # [F, P, K]
    assert seen.mean() > 0.8  # a small room: almost everyone in every view


def test_outside_people_can_hold_a_posture() -> None:
    standing = Scene(_config(3), seed=4)
    seated = Scene(dataclasses.replace(_config(3), outside_posture="sitting"), seed=4)
    a, b = standing.observe_block(0), seated.observe_block(0)
    np.testing.assert_array_equal(a["outside_world"], b["outside_world"])  # same walks
    np.testing.assert_array_equal(a["true_boxes"], b["true_boxes"])  # labelled people unchanged
    tall = a["outside_true_boxes"][..., 3] - a["outside_true_boxes"][..., 1]
    low = b["outside_true_boxes"][..., 3] - b["outside_true_boxes"][..., 1]
    both = np.isfinite(tall) & np.isfinite(low)
    assert np.median(low[both] / tall[both]) < 0.85  # a seated body is shorter in the image
    assert PRESETS["cmc-room"].outside_posture == "sitting"
    with pytest.raises(MomlocError, match="posture"):
        dataclasses.replace(_config(1), outside_posture="dancing")
