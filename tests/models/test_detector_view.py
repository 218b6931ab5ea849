"""``detector_dataset``: real-detector rows labelled with the simulator's truth (used by
``tools/make_demo_model.py`` and ``bench.detector.highres_localization``).

A fake detector returns each camera's reference boxes (in reverse order, plus a ghost box that
matches nobody), except that it misses person 0 in camera 1 and person 2 everywhere: the rows must
carry the true positions, NaN for the missed camera, and no row for the person nobody found.
"""

from __future__ import annotations

import numpy as np
import pytest

from models.detector.base import Detections, PersonDetector
from models.simulate import Scene, get_config
from models.simulate.detector_view import camera_truth, detector_dataset

FRAMES = range(0, 4, 2)


def reference_boxes(scene: Scene, frame: int) -> np.ndarray:
    """[P, K, 4] reference boxes (NaN: not in view), as the truth side of the matching sees them."""
    obs = scene.observe(frame)
    hips = obs.joints[:, 11:13].mean(1)
    out = []
    for k, camera in enumerate(scene.cameras):
        depth = camera.project_depth(hips)[1]
        out.append(camera_truth(obs.true_boxes[:, k], depth, camera.image_size).boxes)
    return np.stack(out, axis=1)


class FakeDetector(PersonDetector):
    """The reference boxes of the frames in ``frames`` order, minus the misses, plus a ghost."""

    kind = "fake"

    def __init__(self, scene: Scene, frames: range) -> None:
        self.scene, self.frames = scene, iter(frames)

    def detect(self, frames):
        truth = reference_boxes(self.scene, next(self.frames))
        out = []
        for k in range(truth.shape[1]):
            keep = np.isfinite(truth[:, k]).all(1)
            keep[2] = False  # person 2: found by nobody
            if k == 1:
                keep[0] = False  # person 0: missed by camera 1
            boxes = truth[keep, k][::-1]
            ghost = np.array([[1.0, 1.0, 9.0, 30.0]])
            boxes = np.concatenate([boxes, ghost]).astype(np.float32)
            out.append(Detections(boxes, np.ones(len(boxes), np.float32)))
        return out


@pytest.fixture()
def scene(monkeypatch: pytest.MonkeyPatch) -> Scene:
    scene = Scene(get_config("indoor-2cam"), seed=3)
    blank = np.zeros((480, 640, 3), np.uint8)
    monkeypatch.setattr(scene, "render", lambda frame, camera: blank)  # the fake never looks
    return scene


def test_rows_carry_the_true_positions_and_nan_for_missed_cameras(scene: Scene) -> None:
    data = detector_dataset(scene, FRAMES, FakeDetector(scene, FRAMES))
    expected_rows = 0
    for f in FRAMES:
        obs, truth = scene.observe(f), reference_boxes(scene, f)
        truth[2] = np.nan
        truth[0, 1] = np.nan
        for p in np.flatnonzero(np.isfinite(truth).all(-1).any(-1)):
            expected_rows += 1
            (row,) = np.flatnonzero((data.frame == f) & (data.track == obs.track[p]))
            np.testing.assert_allclose(data.world[row], obs.world[p, :2], atol=1e-5)
            np.testing.assert_allclose(data.boxes[row], truth[p], atol=1e-3)
    assert data.n == expected_rows > 0
    assert not np.any(data.track == 2)  # found by nobody: no row
    assert np.any(data.track == 0)
    assert np.isnan(data.boxes[data.track == 0, 1]).all()  # the missed camera
    assert data.visible()[:, 0].any() and data.visible()[:, 1].any()
    np.testing.assert_array_equal(data.image_size, [[640, 480], [640, 480]])
