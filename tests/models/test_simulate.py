"""Simulator geometry, reproducibility, dataset output and the `momloc simulate` CLI."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.simulate import (
    PRESETS,
    CameraSpec,
    DetectorProfile,
    PinholeCamera,
    Scene,
    SceneConfig,
    room_config,
    simulate,
)
from models.simulate.skeleton import P


def _side_camera(distortion: tuple[float, float] = (0.0, 0.0)) -> PinholeCamera:
    # At (0, 0, 2) looking along +x, 90° horizontal FOV on 640x480: f = 320 px.
    return PinholeCamera.look_at((0, 0, 2), (10, 0, 2), 90.0, (640, 480), distortion)


def test_known_point_projects_to_hand_computed_pixel() -> None:
    # Looking along +x with z up, camera right is world -y and camera down is world -z.
    # (5, 1, 1) is 5 m ahead, 1 m to the left and 1 m below: u = 320 - 320/5, v = 240 + 320/5.
    pixels, in_front = _side_camera().project(np.array([5.0, 1.0, 1.0]))
    np.testing.assert_allclose(pixels, [256.0, 304.0], atol=1e-9)
    assert bool(in_front)
    # With k1 = 0.1: r² = 0.2² + 0.2² = 0.08, both offsets grow by 1 + 0.1 * 0.08.
    pixels, _ = _side_camera((0.1, 0.0)).project(np.array([5.0, 1.0, 1.0]))
    np.testing.assert_allclose(pixels, [320 - 64 * 1.008, 240 + 64 * 1.008], atol=1e-9)


def test_projection_matrix_agrees_with_project() -> None:
    camera = PinholeCamera.look_at((0.05, 0.05, 2.3), (5, 5, 0.9), 65.0, (640, 480))
    points = np.random.default_rng(0).uniform([1, 1, 0], [9, 9, 2], size=(50, 3))
    homogeneous = np.hstack([points, np.ones((50, 1))]) @ camera.projection_matrix.T
    pixels, in_front = camera.project(points)
    assert in_front.all()
    np.testing.assert_allclose(homogeneous[:, :2] / homogeneous[:, 2:], pixels, atol=1e-6)
    np.testing.assert_allclose(camera.position, [0.05, 0.05, 2.3], atol=1e-12)
    assert camera.hfov_deg == pytest.approx(65.0)


def test_webcam_cameras_are_mounted_high_and_look_into_the_room() -> None:
    for config in PRESETS.values():
        if config.name == "cmc-room":  # a real lab's 82-85° cameras: test_simulate_outside
            continue
        for spec in config.cameras:
            camera = spec.camera()
            assert 1.8 <= camera.position[2] <= 2.6
            assert 55 <= camera.hfov_deg <= 75
            centre = np.array([*np.array(config.room) / 2, 1.0])
            pixel, in_front = camera.project(centre)
            assert in_front and 0 < pixel[0] < camera.image_size[0]


@pytest.mark.parametrize("distortion", [(0.0, 0.0), (-0.12, 0.02)])
def test_true_boxes_contain_projected_joints_and_world_is_under_mid_hip(
    distortion: tuple[float, float],
) -> None:
    scene = Scene(room_config("t", 8, 6, 3, people=4, distortion=distortion), seed=3)
    checked = 0
    for frame in range(0, 200, 7):
        obs = scene.observe(frame)
        mid_hip = (obs.joints[:, P["left_hip"], :2] + obs.joints[:, P["right_hip"], :2]) / 2
        np.testing.assert_allclose(obs.world, mid_hip, atol=1e-9)
        assert (obs.joints[..., 2] >= 0).all() and (obs.joints[..., 2] < 1.95).all()
        for k, camera in enumerate(scene.cameras):
            pixels, _ = camera.project(obs.joints)
            box = obs.true_boxes[:, k]
            seen = np.isfinite(box).all(-1)
            inside = (pixels >= box[:, None, :2]) & (pixels <= box[:, None, 2:])
            assert inside[seen].all()
            # The body volume is wider than the joints: the box is larger than the joints' box.
            joint_height = pixels[..., 1].max(-1) - pixels[..., 1].min(-1)
            assert (box[seen, 3] - box[seen, 1] > joint_height[seen] * 1.05).all()
            checked += int(seen.sum())
    assert checked > 100


def test_person_behind_camera_or_out_of_view_gives_nan() -> None:
    outward = CameraSpec((5.0, 0.05, 2.3), (5.0, -5.0, 1.0))  # on a wall, facing out of the room
    narrow = CameraSpec((0.05, 0.05, 2.3), (9.0, 9.0, 0.9), hfov_deg=20.0)
    scene = Scene(SceneConfig("t", (10, 10), (outward, narrow), people=3), seed=1)
    behind = outside = inside = 0
    for frame in range(0, 640, 5):
        obs = scene.observe(frame)
        assert np.isnan(obs.true_boxes[:, 0]).all() and np.isnan(obs.boxes[:, 0]).all()
        assert np.isnan(obs.keypoints[:, 0]).all()
        behind += obs.world.shape[0]
        hip = np.concatenate([obs.world, np.full((3, 1), 0.9)], 1)
        pixels, _ = scene.cameras[1].project(hip)
        far_out = (pixels[:, 0] < -300) | (pixels[:, 0] > 940)
        assert np.isnan(obs.boxes[far_out, 1]).all()
        assert np.isnan(obs.true_boxes[far_out, 1]).all()
        outside += int(far_out.sum())
        inside += int(np.isfinite(obs.boxes[~far_out, 1]).all(-1).sum())
    assert behind > 100 and outside > 20 and inside > 20


def test_same_seed_same_file_and_different_seed_differs(tmp_path: Path) -> None:
    a = simulate("indoor-2cam", 300, seed=5).dataset
    b = simulate("indoor-2cam", 300, seed=5).dataset
    c = simulate("indoor-2cam", 300, seed=6).dataset
    a.save(tmp_path / "a.npz")
    b.save(tmp_path / "b.npz")
    for key, value in MomDataset.load(tmp_path / "a.npz").arrays().items():
        np.testing.assert_array_equal(value, MomDataset.load(tmp_path / "b.npz").arrays()[key])
    assert a.n != c.n or not np.array_equal(a.world, c.world)


def test_observe_agrees_with_simulate_rows() -> None:
    result = simulate("indoor-4cam", 200, seed=2)
    data, scene = result.dataset, Scene(PRESETS["indoor-4cam"], seed=2)
    assert result.projections.shape == (4, 3, 4)
    for row in (0, data.n // 2, data.n - 1):
        obs = scene.observe(int(data.frame[row]))
        person = int(data.track[row])
        np.testing.assert_allclose(data.world[row], obs.world[person], atol=1e-5)
        np.testing.assert_allclose(data.boxes[row], obs.boxes[person], atol=1e-3)
    # Rows are exactly the instances seen by at least one camera.
    seen = sum(int(np.isfinite(scene.observe(f).boxes).all(-1).any(-1).sum()) for f in range(200))
    assert data.n == seen
    assert (np.diff(data.frame) >= 0).all()


@pytest.mark.parametrize("cameras", [1, 5, 9])
def test_any_camera_count(cameras: int) -> None:
    data = simulate(room_config("r", 7, 5, cameras, people=2), 64, seed=0).dataset
    assert data.num_cameras == cameras
    assert data.keypoints is not None and data.keypoints.shape[1:] == (cameras, 17, 3)


def test_bad_configs_are_user_errors() -> None:
    with pytest.raises(MomlocError, match=r"available: .*indoor-2cam"):
        simulate("nowhere", 10)
    with pytest.raises(MomlocError, match="between 1 and 9"):
        room_config("r", 5, 5, 10)
    with pytest.raises(MomlocError, match="people"):
        simulate("indoor-2cam", 10, people=0)


def test_exact_noise_boxes_are_clipped_true_boxes() -> None:
    config = SceneConfig(
        "t",
        (10, 10),
        PRESETS["indoor-2cam"].cameras,
        people=1,
        detector_profile=DetectorProfile.exact(),
    )
    scene = Scene(config, seed=0)
    for frame in range(0, 64, 4):
        obs = scene.observe(frame)
        seen = np.isfinite(obs.boxes).all(-1)
        clipped = np.clip(obs.true_boxes, 0, [640, 480, 640, 480])
        np.testing.assert_allclose(obs.boxes[seen], clipped[seen], atol=1e-6)


def test_cli_writes_valid_file_and_prints_summary(tmp_path: Path) -> None:
    out = tmp_path / "s.npz"
    cmd = [
        sys.executable,
        "-m",
        "service.cli",
        "simulate",
        "--preset",
        "living-room",
        "--frames",
        "100",
        "--seed",
        "3",
        "--out",
        str(out),
        "--people",
        "2",
        "--fps",
        "10",
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    data = MomDataset.load(out)
    assert data.summary() in done.stdout and len(done.stdout.strip().splitlines()) == 1
    assert set(data.track.tolist()) == {0, 1}
    bad_cmd = [*cmd[:5], "nope", *cmd[6:]]
    bad = subprocess.run(bad_cmd, capture_output=True, text=True, check=False)
    assert bad.returncode == 2 and "available:" in bad.stderr and "Traceback" not in bad.stderr


def test_walker_cache_is_bounded_and_replays_evicted_frames(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import models.simulate.people as people

    monkeypatch.setattr(people, "_KEEP", 2)
    reference = people.Walkers((10, 10), 3, 15.0, np.random.default_rng(1)).states(0, 3000)
    walkers = people.Walkers((10, 10), 3, 15.0, np.random.default_rng(1))
    late = walkers.states(2500, 3000)  # integrates chunks 0..5, keeps only 4 and 5
    assert len(walkers._chunks) == 2
    early = walkers.states(100, 700)  # chunks 0 and 1 are replayed from their checkpoints
    again = walkers.states(2999, 3000)
    np.testing.assert_array_equal(late.position, reference.position[2500:])
    np.testing.assert_array_equal(early.phase, reference.phase[100:700])
    np.testing.assert_array_equal(again.heading, reference.heading[2999:])
    speed = np.linalg.norm(np.diff(reference.position, axis=0), axis=-1) * 15.0
    assert speed.max() < 2.0 and 0.5 < np.median(speed) < 1.6  # walking, no jumps
    assert (reference.position > 0).all() and (reference.position < 10).all()


def test_walkers_keep_their_spacing_at_any_frame_rate() -> None:
    import models.simulate.people as people

    def closest(fps: float, **spacing: float) -> float:
        """5th percentile of the distance to the nearest other, 8 people, 60 s at 4 samples/s."""
        walkers = people.Walkers((4.27, 3.41), 8, fps, np.random.default_rng(2), **spacing)
        xy = walkers.states(0, int(60 * fps)).position[:: round(fps / 4)]
        d = np.linalg.norm(xy[:, :, None] - xy[:, None], axis=-1) + 99 * np.eye(8)
        return float(np.percentile(d.min(-1), 5))

    assert people.Walkers((5, 5), 2, 4.0, np.random.default_rng(0)).substeps == 4
    assert people.Walkers((5, 5), 2, 15.0, np.random.default_rng(0)).substeps == 1
    slow, fast = closest(4.0), closest(16.0)
    assert abs(slow - fast) < 0.05 and slow > 0.35  # 4 fps stepped once a frame: 0.33 m
    assert closest(4.0, separation=1.0, repulsion=0.06) > slow


def test_cli_custom_room_cameras_and_bump(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from service.cli import main

    out = tmp_path / "c.npz"
    args = ["simulate", "--room", "6x4", "--cameras", "3", "--frames", "130", "--out", str(out)]
    assert main([*args, "--bump", "0,64,10,-5", "--bump", "2,0,0,0,1.5"]) == 0
    data = MomDataset.load(out)
    assert data.num_cameras == 3 and "3 cameras" in capsys.readouterr().out
    assert main([*args[:-1], str(tmp_path / "plain.npz")]) == 0
    plain = MomDataset.load(tmp_path / "plain.npz")
    early, early_plain = data.frame < 64, plain.frame < 64
    np.testing.assert_array_equal(data.boxes[early, :2], plain.boxes[early_plain, :2])
    assert not np.array_equal(data.boxes[early, 2], plain.boxes[early_plain, 2])  # rolled
    late = data.subset(~early).boxes[:, 0]
    late_plain = plain.subset(~early_plain).boxes[:, 0]
    assert late.shape == late_plain.shape  # same people seen (seeded), so rows line up
    both = np.isfinite(late).all(-1) & np.isfinite(late_plain).all(-1)
    shift = np.median(late[both] - late_plain[both], axis=0)
    np.testing.assert_allclose(shift, [10, -5, 10, -5], atol=0.5)
    assert (data.world[:, 0] < 6).all() and (data.world[:, 1] < 4).all()
    assert main([*args[:-2], "--out", str(out), "--room", "6by4"]) == 2
    assert main([*args, "--bump", "1,2"]) == 2
    assert "CAM,FRAME,DX,DY" in capsys.readouterr().err
