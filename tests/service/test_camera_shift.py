"""The image-based camera-moved check on frames rendered by the simulator, bumped mid-run."""

from __future__ import annotations

import numpy as np
import pytest

from models.simulate import Perturbation, Scene, get_config
from service.camera_health.image_shift import CameraShiftMonitor, ShiftWorker, rigid_ransac

FPS = 30
BUMP = 14 * FPS  # frame of the bump: references are ready after ~5 s, baseline runs ~9 s


def _run(dx: float, dy: float, roll: float, camera: int = 1, seconds: int = 24):
    config = get_config(
        "indoor-2cam",
        people=3,
        fps=FPS,
        perturbations=(Perturbation(camera=camera, start_frame=BUMP, dx=dx, dy=dy, roll_deg=roll),),
    )
    scene = Scene(config, seed=5)
    monitor = CameraShiftMonitor(2)
    history = []
    for frame in range(0, seconds * FPS, FPS // 2):  # twice a second; the monitor checks 1/s
        t = frame / FPS
        monitor.offer(t, [scene.render(frame, k) for k in range(2)])
        history.append((frame, monitor.status()))
    return history


def test_render_draws_the_perturbed_view_after_start_frame() -> None:
    config = get_config(
        "indoor-2cam", people=1, fps=FPS, perturbations=(Perturbation(1, 10, dx=20.0),)
    )
    scene = Scene(config, seed=5)

    def change(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.abs(a.astype(int) - b).mean())

    before, after = scene.render(9, 1), scene.render(10, 1)
    steady = change(scene.render(9, 0), scene.render(10, 0))  # camera 0: only the person moved
    assert change(before, after) > 5 * steady
    # the view moved 20 px to the right: columns line up best when shifted back by 20
    best = min(range(0, 31), key=lambda d: change(after[:, 40:600], before[:, 40 - d : 600 - d]))
    assert best == 20


@pytest.mark.parametrize(
    ("dx", "dy", "roll", "low", "high"),
    [(20.0, 0.0, 0.0, 18.0, 22.0), (0.0, 0.0, 1.5, 8.0, 13.0)],
    ids=["horizontal-20px", "roll-1.5deg"],
)
def test_alert_on_the_bumped_camera_only(
    dx: float, dy: float, roll: float, low: float, high: float
) -> None:
    history = _run(dx, dy, roll)
    before = [states for frame, states in history if frame < BUMP]
    after = [states for frame, states in history if frame >= BUMP + 6 * FPS]
    assert before[-1][0].reference == before[-1][1].reference == "ready"
    assert not any(s.moved for states in before for s in states)
    assert max(s.shift_px or 0.0 for states in before for s in states) < 1.5
    assert after and all(states[1].moved and not states[0].moved for states in after)
    shift = after[-1][1].shift_px
    assert low < shift < high  # 1.5° about the centre moves the corners 400 px * 0.026 = 10.5 px
    assert after[-1][0].shift_px < 1.5


def test_alert_clears_when_the_camera_is_put_back() -> None:
    config = get_config(
        "indoor-2cam",
        people=2,
        fps=FPS,
        perturbations=(Perturbation(0, 8 * FPS, dy=-15.0), Perturbation(0, 16 * FPS)),
    )
    scene = Scene(config, seed=3)
    monitor = CameraShiftMonitor(2)
    moved = []
    for frame in range(0, 24 * FPS, FPS):
        monitor.offer(frame / FPS, [scene.render(frame, 0), None])
        moved.append(monitor.status()[0].moved)
    assert moved[13:16] == [True] * 3 and moved[-3:] == [False] * 3
    assert monitor.status()[1].reference == "collecting"  # camera 1 never delivered pixels


def test_reset_takes_a_new_reference() -> None:
    monitor = CameraShiftMonitor(1, reference_frames=2)
    rng = np.random.default_rng(0)
    image = (rng.random((240, 320)) * 255).astype(np.uint8)
    for t in range(3):
        monitor.offer(float(t), [image])
    assert monitor.status()[0].reference == "ready"
    assert monitor.status()[0].shift_px == pytest.approx(0.0, abs=0.05)
    monitor.reset()
    assert monitor.status()[0].reference == "collecting"


def test_offer_is_rate_limited_and_worker_delivers() -> None:
    monitor = CameraShiftMonitor(1, reference_frames=1, interval_s=1.0)
    image = (np.random.default_rng(1).random((240, 320)) * 255).astype(np.uint8)
    assert monitor.offer(0.0, [image]) and not monitor.offer(0.5, [image])
    assert not monitor.offer(1.0, [None])  # frames without pixels are never checked
    worker = ShiftWorker(monitor)
    worker.submit(1.0, [np.roll(image, 9, axis=1)])
    worker.stop()
    worker = ShiftWorker(monitor, threaded=False)
    worker.submit(2.0, [np.roll(image, 9, axis=1)])
    assert monitor.status()[0].shift_px == pytest.approx(9.0, abs=0.3)


def test_rigid_ransac_recovers_rotation_despite_outliers() -> None:
    rng = np.random.default_rng(2)
    src = rng.random((60, 2)) * 300
    angle = np.radians(2.0)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    dst = src @ rot.T + [4.0, -3.0]
    dst[:20] += rng.normal(0, 30, (20, 2))  # people in front of a third of the corners
    found = rigid_ransac(src, dst, 1.0)
    assert found is not None
    motion, keep = found
    assert np.allclose(motion[:, :2], rot, atol=1e-6) and np.allclose(motion[:, 2], [4, -3])
    assert keep[20:].all() and keep[:20].sum() <= 2


def test_a_bump_during_reference_collection_restarts_it() -> None:
    rng = np.random.default_rng(4)
    image = (rng.random((240, 320)) * 255).astype(np.uint8)
    monitor = CameraShiftMonitor(1, reference_frames=3)
    frames = [image, image, np.roll(image, 12, axis=1)]  # bumped at the third frame
    for i, frame in enumerate(frames):
        monitor.offer(float(i), [frame])
    assert monitor.status()[0].reference == "collecting"
    for t in (3.0, 4.0, 5.0):
        monitor.offer(t, [frames[-1]])
    assert monitor.status()[0].reference == "ready"
    assert monitor.status()[0].shift_px == pytest.approx(0.0, abs=0.05)
