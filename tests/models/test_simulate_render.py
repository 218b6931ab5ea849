"""Rendered frames: right shape, people painted where their true boxes are, background elsewhere."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from models.simulate import PRESETS, Perturbation, Scene, get_config
from models.simulate.render import Renderer, render_background
from models.simulate.skeleton import MID_HIP


def _changed(scene: Scene, frame: int, camera: int) -> np.ndarray:
    image = scene.render(frame, camera)
    background = _renderer(scene).background(scene.cameras_at(frame)[camera])
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


def _painted(image: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Pixels a body was painted on: changed, and not merely darkened by a floor shadow."""
    img, bg = image.astype(int), background.astype(int)
    changed = np.abs(img - bg).sum(-1) > 30
    shadow = np.abs(img - (bg * 0.8).astype(int)).sum(-1) < 12
    return changed & ~shadow


def test_painted_body_fills_its_perspective_box_near_and_far() -> None:
    """The drawn person spans its true box (the projected body volume) at every distance:
    sizes follow the pinhole perspective point by point, small far away, large close by."""
    scene = Scene(get_config("office-3cam", people=1), seed=5)
    heights = []
    for frame in range(0, 900, 45):
        for camera in range(scene.num_cameras):
            box = scene.observe(frame).true_boxes[0, camera]
            if not np.isfinite(box).all() or box[0] < 2 or box[1] < 2:
                continue
            if box[2] > 638 or box[3] > 478:
                continue  # truncated at the border
            image = scene.render(frame, camera)
            background = _renderer(scene).background(scene.cameras_at(frame)[camera])
            ys, xs = np.nonzero(_painted(image, background))
            height = box[3] - box[1]
            assert abs(ys.min() - box[1]) < 0.04 * height + 2, (frame, camera)
            assert abs(ys.max() - box[3]) < 0.05 * height + 2, (frame, camera)
            assert xs.min() > box[0] - 3 and xs.max() < box[2] + 3, (frame, camera)
            heights.append(height)
    assert len(heights) >= 10
    assert min(heights) < 120 and max(heights) > 200  # near and far both checked


def test_nearer_person_is_painted_over_the_farther() -> None:
    from models.simulate.render import draw_people

    scene = Scene(PRESETS["office-3cam"], seed=2)
    scene.render(0, 0)
    renderer = _renderer(scene)
    checked = 0
    for frame in range(0, 1200, 10):
        obs = scene.observe(frame)
        points = scene.body_points(frame)
        for camera in range(scene.num_cameras):
            cam = scene.cameras[camera]
            boxes = obs.true_boxes[:, camera]
            depth = cam.project_depth(points[:, MID_HIP])[1]
            for a, b in [(a, b) for a in range(len(boxes)) for b in range(len(boxes)) if a != b]:
                if not (np.isfinite(boxes[a]).all() and np.isfinite(boxes[b]).all()):
                    continue
                if depth[a] >= depth[b]:
                    continue
                ix = min(boxes[a, 2], boxes[b, 2]) - max(boxes[a, 0], boxes[b, 0])
                iy = min(boxes[a, 3], boxes[b, 3]) - max(boxes[a, 1], boxes[b, 1])
                if ix <= 10 or iy <= 10:
                    continue
                background = renderer.background(cam)
                both, alone = background.copy(), background.copy()
                pair = [b, a]
                draw_people(both, cam, points[pair], scene.walkers.heights[pair],
                            [renderer.looks[i] for i in pair], renderer.light)  # fmt: skip
                draw_people(alone, cam, points[[a]], scene.walkers.heights[[a]],
                            [renderer.looks[a]], renderer.light)  # fmt: skip
                # inside the nearer silhouette (its anti-aliased rim blends with what is behind)
                mask = cv2.erode(_painted(alone, background).astype(np.uint8), np.ones((3, 3))) > 0
                same = (np.abs(both.astype(int) - alone.astype(int)).sum(-1) <= 3)[mask]
                assert same.mean() > 0.97, (frame, camera, a, b, same.mean())
                checked += 1
        if checked >= 5:
            break
    assert checked >= 5


def test_rooms_are_furnished_the_same_for_every_camera() -> None:
    from models.simulate.room import room_decor

    for name in ("indoor-2cam", "living-room", "office-3cam"):
        config = PRESETS[name]
        decor = room_decor(config.room, config.wall_height)
        again = room_decor(config.room, config.wall_height)  # deterministic
        assert again.furniture == decor.furniture and again.decals == decor.decals
        assert len(decor.furniture) + len(decor.decals) >= 3, name
        for item in decor.furniture:  # against a wall, where nobody walks
            lo, hi = np.array(item.lo[:2]), np.array(item.hi[:2])
            gap = np.minimum(lo, np.array(config.room) - hi)
            assert (np.sort(gap)[0] <= 1e-9) and (hi - lo).min() <= 0.3 + 1e-9, (name, item)
        bare = dataclasses.replace(decor, furniture=(), decals=())
        for camera in Scene(config, seed=0).cameras:  # every camera sees some of it
            plain, furnished = (
                render_background(camera, config.room, config.wall_height, grain=0, decor=d)
                for d in (bare, decor)
            )
            assert (np.abs(plain.astype(int) - furnished.astype(int)).sum(-1) > 30).mean() > 0.02


def _renderer(scene: Scene) -> Renderer:
    """The scene's renderer (made by its first ``render``)."""
    assert scene._renderer is not None
    return scene._renderer
