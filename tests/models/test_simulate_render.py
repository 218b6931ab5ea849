"""Rendered frames: right shape, people painted where their true boxes are, background elsewhere."""

from __future__ import annotations

import numpy as np

from models.simulate import PRESETS, Perturbation, Scene, get_config
from models.simulate.render import render_background


def _changed(scene: Scene, frame: int, camera: int) -> np.ndarray:
    image = scene.render(frame, camera)
    background = scene._renderer.background(scene.cameras_at(frame)[camera])
    return np.abs(image.astype(int) - background.astype(int)).sum(-1) > 30


def test_render_shape_and_person_inside_true_box() -> None:
    scene = Scene(get_config("living-room", people=1), seed=4)
    checked = 0
    for frame in (0, 40, 80, 120):
        for camera in range(scene.num_cameras):
            image = scene.render(frame, camera)
            assert image.shape == (480, 640, 3) and image.dtype == np.uint8
            box = scene.observe(frame).true_boxes[0, camera]
            changed = _changed(scene, frame, camera)
            if not np.isfinite(box).all():
                continue
            x0, y0 = np.floor(np.clip(box[:2], 0, [640, 480])).astype(int)
            x1, y1 = np.ceil(np.clip(box[2:], 0, [640, 480])).astype(int)
            inside = changed[y0:y1, x0:x1]
            if inside.size < 400:
                continue
            # The body fills a good part of its box; almost nothing is painted far outside it
            # (the floor shadow may stick out below the feet a little).
            assert inside.mean() > 0.25
            outside = changed.copy()
            outside[max(y0 - 4, 0) : y1 + 30, max(x0 - 30, 0) : x1 + 30] = False
            assert outside.mean() < 0.002
            checked += 1
    assert checked >= 3


def test_every_person_in_view_is_painted() -> None:
    scene = Scene(PRESETS["indoor-2cam"], seed=0)
    image = scene.render(10, 0)
    assert image.shape == (480, 640, 3)
    # Everybody whose true box is in view leaves paint inside it.
    obs = scene.observe(10)
    changed = _changed(scene, 10, 0)
    for box in obs.true_boxes[:, 0]:
        if np.isfinite(box).all():
            x0, y0 = np.clip(box[:2], 0, [639, 479]).astype(int)
            x1, y1 = np.clip(box[2:], 1, [640, 480]).astype(int)
            assert changed[y0:y1, x0:x1].any()


def test_background_is_room_and_perturbed_camera_shifts_the_image() -> None:
    config = get_config("indoor-2cam", perturbations=(Perturbation(0, 5, dx=12, dy=0),))
    scene = Scene(config, seed=0)
    before = scene._renderer  # not yet created
    assert before is None
    a = render_background(scene.cameras_at(0)[0], config.room, config.wall_height, grain=0)
    b = render_background(scene.cameras_at(5)[0], config.room, config.wall_height, grain=0)
    assert a.shape == (480, 640, 3)
    # Floor (bottom) and ceiling (top) have different colours.
    assert np.abs(a[-20:].mean((0, 1)) - a[:20].mean((0, 1))).sum() > 20
    # A pure image shift: b[:, x + 12] == a[:, x].
    diff = np.abs(b[:, 12:].astype(int) - a[:, :-12].astype(int)).mean()
    unshifted = np.abs(b.astype(int) - a.astype(int)).mean()
    assert diff < 0.05 < 1.0 < unshifted
