"""Detector noise: the ``ideal`` profile keeps the former noise statistics; occlusion, truncation,
keypoints and camera bumps. (Measured profiles: ``test_simulate_profiles.py``.)"""

from __future__ import annotations

import dataclasses

import numpy as np

from models.simulate import (
    CameraSpec,
    DetectorProfile,
    Perturbation,
    Scene,
    SceneConfig,
    get_config,
    simulate,
)
from models.simulate.noise import detect
from models.simulate.profile import Table, load_profile

SIZE = np.array([[640, 480]])


def _detect(boxes: list[list[float]], depths: list[float], config: DetectorProfile | None = None,
            joints: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    true = np.array(boxes, float)[None, None]  # [F=1, K=1, P, 4]
    p = true.shape[2]
    if joints is None:
        joints = np.full((1, 1, p, 17, 2), 320.0)
    boxes_out, keypoints = detect(
        true, np.array(depths, float)[None, None], joints, np.zeros((1, 1, p, 17), bool), SIZE,
        config or DetectorProfile.exact(), np.random.default_rng(0),
    )  # fmt: skip
    return boxes_out[0, 0], keypoints[0, 0]


def test_ideal_profile_keeps_the_former_noise_statistics() -> None:
    # The flat model the simulator used before detector profiles: 3 % misses, edge jitter 3 %,
    # scale 5 %, all pinned by the `ideal` profile for comparison tables.
    camera = CameraSpec((0.05, 4.0, 2.3), (8.0, 4.0, 0.9), 60.0)
    config = SceneConfig("stats", (12.0, 8.0), (camera,), people=1, detector_profile="ideal")
    scene = Scene(config, seed=11)
    true_blocks, noisy_blocks = [], []
    for block in range(60):
        obs = scene.observe_block(block)
        true_blocks.append(obs["true_boxes"][:, 0, 0])
        noisy_blocks.append(obs["boxes"][:, 0, 0])
    true, noisy = np.concatenate(true_blocks), np.concatenate(noisy_blocks)
    h = true[:, 3] - true[:, 1]
    margin = 0.2 * h
    clean = (true[:, 0] > margin) & (true[:, 1] > margin) & (true[:, 2] < 640 - margin)
    clean &= (true[:, 3] < 480 - margin) & (h > 40)
    assert clean.sum() > 1500
    t, b, h = true[clean], noisy[clean], h[clean]
    missed = np.isnan(b).all(-1)
    assert 0.022 < missed.mean() < 0.04  # documented 3 % (no occlusion, no truncation here)
    t, b, h = t[~missed], b[~missed], h[~missed]
    # Centre shift = mean of two independent edge jitters: sigma = jitter / sqrt(2).
    shift = ((b[:, 0] + b[:, 2]) - (t[:, 0] + t[:, 2])) / 2 / h
    assert abs(np.std(shift) - 0.03 / np.sqrt(2)) < 0.003
    assert abs(np.mean(shift)) < 0.003
    # Height ratio - 1 = scale error + difference of two edge jitters.
    ratio = (b[:, 3] - b[:, 1]) / h - 1
    assert abs(np.std(ratio) - np.sqrt(0.05**2 + 2 * 0.03**2)) < 0.007


def test_occlusion_misses_hidden_person_and_shrinks_half_hidden_one() -> None:
    near = [100.0, 100.0, 200.0, 400.0]  # body region: x 115..185 (70 % of the width)
    boxes, _ = _detect([near, [120, 150, 180, 350], [160, 150, 260, 350]], [3.0, 6.0, 6.0])
    np.testing.assert_allclose(boxes[0], near)
    assert np.isnan(boxes[1]).all()  # entirely behind the near person
    # A quarter covered (x 160..185): the detector boxes mostly the visible part.
    assert 172 <= boxes[2, 0] <= 190 and boxes[2, 2] == 260
    assert boxes[2, 1] == 150 and boxes[2, 3] == 350
    # The same box in front is untouched.
    boxes, _ = _detect([near, [160, 150, 260, 350]], [6.0, 3.0])
    np.testing.assert_allclose(boxes[1], [160, 150, 260, 350])


def test_truncation_clips_and_drops_mostly_outside_boxes() -> None:
    boxes, _ = _detect(
        [[-50, 100, 50, 300], [-90, 100, 10, 300], [700, 100, 800, 300], [600, 300, 660, 500]],
        [4.0, 4.5, 5.0, 5.5],
    )
    np.testing.assert_allclose(boxes[0], [0, 100, 50, 300])
    assert np.isnan(boxes[1]).all() and np.isnan(boxes[2]).all()
    np.testing.assert_allclose(boxes[3], [600, 300, 640, 480])


def test_keypoints_confidence_low_when_occluded_and_nan_outside() -> None:
    joints = np.full((1, 1, 2, 17, 2), 150.0)
    joints[0, 0, 1, :, 0] = 240.0  # far person's joints to the right of the near body ...
    joints[0, 0, 1, :5, 0] = 170.0  # ... except its head, which is behind the near body
    joints[0, 0, 1, 16] = [-5.0, 300.0]  # and one ankle off the image
    _, keypoints = _detect([[100, 100, 200, 400], [160, 150, 260, 350]], [3.0, 6.0],
                           joints=joints)  # fmt: skip
    far = keypoints[1]
    assert (far[:5, 2] < 0.4).all() and (far[5:16, 2] > 0.5).all()
    assert np.isnan(far[16]).all()
    np.testing.assert_allclose(far[5:16, :2], np.tile([240.0, 150.0], (11, 1)))


def test_camera_bump_shifts_boxes_from_its_frame_on() -> None:
    bump = Perturbation(camera=0, start_frame=64, dx=15.0, dy=-8.0)
    plain = Scene(get_config("indoor-2cam"), seed=3)
    bumped = Scene(get_config("indoor-2cam", perturbations=(bump,)), seed=3)
    np.testing.assert_array_equal(plain.projection_matrices(), bumped.projection_matrices())
    np.testing.assert_array_equal(bumped.projection_matrices(63), plain.projection_matrices())
    world = np.array([4.0, 6.0, 1.0, 1.0])
    a = plain.projection_matrices()[0] @ world
    b = bumped.projection_matrices(64)[0] @ world
    np.testing.assert_allclose(b[:2] / b[2] - a[:2] / a[2], [15.0, -8.0], atol=1e-9)

    before = bumped.observe_block(0)
    np.testing.assert_array_equal(before["boxes"], plain.observe_block(0)["boxes"])
    p, q = plain.observe_block(1), bumped.observe_block(1)
    both = np.isfinite(p["true_boxes"][:, :, 0]).all(-1) & np.isfinite(
        q["true_boxes"][:, :, 0]
    ).all(-1)
    shift = q["true_boxes"][:, :, 0][both] - p["true_boxes"][:, :, 0][both]
    np.testing.assert_allclose(shift, np.tile([15.0, -8.0, 15.0, -8.0], (len(shift), 1)), atol=1e-6)
    np.testing.assert_array_equal(q["boxes"][:, :, 1], p["boxes"][:, :, 1])  # camera 1 untouched
    seen = np.isfinite(p["boxes"][:, :, 0]).all(-1) & np.isfinite(q["boxes"][:, :, 0]).all(-1)
    moved = q["boxes"][:, :, 0][seen] - p["boxes"][:, :, 0][seen]
    exact = np.isclose(moved, [15.0, -8.0, 15.0, -8.0], atol=1e-3).all(-1)
    assert seen.sum() > 50 and exact.mean() > 0.8  # the rest were clipped at the border


def test_camera_roll_rotates_about_principal_point() -> None:
    roll = Perturbation(camera=0, start_frame=0, roll_deg=3.0)
    scene = Scene(get_config("indoor-2cam", perturbations=(roll,)), seed=0)
    base, rolled = scene.cameras[0], scene.cameras_at(0)[0]
    point = np.array([6.0, 7.0, 0.5])
    a, _ = base.project(point)
    b, _ = rolled.project(point)
    centre = base.K[:2, 2]
    angle = np.degrees(np.arctan2(*(b - centre)[::-1]) - np.arctan2(*(a - centre)[::-1]))
    assert abs(angle - 3.0) < 1e-6 or abs(angle + 3.0) < 1e-6
    assert abs(np.linalg.norm(b - centre) - np.linalg.norm(a - centre)) < 1e-6


def test_simulate_accepts_a_perturbation() -> None:
    bump = Perturbation(camera=1, start_frame=10, dx=30.0)
    result = simulate("indoor-2cam", 64, seed=0, perturbation=bump)
    assert result.scene.config.perturbations == (bump,)
    np.testing.assert_array_equal(
        result.projections, Scene(get_config("indoor-2cam")).projection_matrices()
    )


def test_box_noise_is_correlated_in_time_like_a_detector() -> None:
    from models.simulate.noise import correlated_normals

    rng = np.random.default_rng(0)
    history, white = rng.standard_normal((64, 4000)), rng.standard_normal((64, 4000))
    series = correlated_normals(white, history, fps=15.0, correlation_time=0.2)
    rho = np.exp(-1 / 3)
    assert abs(series.std() - 1) < 0.02
    lag1 = (series[1:] * series[:-1]).mean()
    assert abs(lag1 - rho) < 0.03
    assert correlated_normals(white, history, 15.0, 0.0) is white

    # In a scene: consecutive frames share most of their error, also across a block boundary.
    camera = CameraSpec((0.05, 4.0, 2.3), (8.0, 4.0, 0.9), 60.0)
    ideal = load_profile("ideal")  # edge errors correlated over 0.2 s; no misses for this test
    noise = dataclasses.replace(
        ideal, miss=dataclasses.replace(ideal.miss, height=Table((0,), (0,)))
    )
    scene = Scene(
        SceneConfig("c", (12.0, 8.0), (camera,), people=1, detector_profile=noise), seed=1
    )
    blocks = []
    for block in range(8):
        obs = scene.observe_block(block)
        b, t = obs["boxes"][:, 0, 0], obs["true_boxes"][:, 0, 0]
        blocks.append((b[:, 0] + b[:, 2] - t[:, 0] - t[:, 2]) / 2 / (t[:, 3] - t[:, 1]))
    err = np.concatenate(blocks)
    pairs = np.isfinite(err[1:]) & np.isfinite(err[:-1])
    corr = np.corrcoef(err[1:][pairs], err[:-1][pairs])[0, 1]
    assert 0.55 < corr < 0.9
    # Blocks filtered one at a time chain into one stationary sequence (no jump at boundaries).
    w0, w1, w2 = (rng.standard_normal((64, 3)) for _ in range(3))
    first = correlated_normals(w1, w0, 15.0, 0.2)
    second = correlated_normals(w2, w1, 15.0, 0.2)
    joined = np.concatenate([first, second])
    full = correlated_normals(np.concatenate([w1, w2]), w0, 15.0, 0.2)
    np.testing.assert_allclose(joined, full, atol=1e-12)
