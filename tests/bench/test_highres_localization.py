"""The pure pieces of ``bench.detector.highres_localization``: the all-instances accuracy (a missed
instance is a miss), the camera shares, the instances-in-view count (the same truth
``detector_dataset`` matches against), and the markdown written from a tiny fake result."""

from __future__ import annotations

import numpy as np
import pytest

from bench.detector.highres_localization import (
    SettingResult,
    all_instances_accuracy,
    camera_shares,
    in_view,
    report,
    setting_name,
)
from models.detector.base import Detections, PersonDetector
from models.simulate import Scene, get_config
from models.simulate.detector_view import camera_truth, detector_dataset


def test_a_missed_instance_counts_as_a_miss() -> None:
    errors = np.array([0.1, 0.49, 0.6, np.nan])  # found: 2 close, 1 far, 1 without a position
    assert all_instances_accuracy(errors, 4) == pytest.approx(50.0)
    assert all_instances_accuracy(errors, 8) == pytest.approx(25.0)  # 4 more nobody found
    assert all_instances_accuracy(errors, 8, threshold=1.0) == pytest.approx(37.5)
    with pytest.raises(ValueError):
        all_instances_accuracy(errors, 3)  # more found than in view


def test_camera_shares_are_shares_of_everything_in_view() -> None:
    shares = camera_shares(np.array([1, 2, 2, 3, 5]), 10)
    assert shares == pytest.approx({"1": 10.0, "2": 20.0, "3+": 20.0})


def test_setting_names() -> None:
    assert setting_name(None, (320, 256)) == "fixed 320x256"
    assert setting_name(3.0, (640, 384)) == "max_shrink 3 (640x384)"


class PerfectDetector(PersonDetector):
    """Every reference box of the frames in order: finds exactly what is in view."""

    kind = "perfect"

    def __init__(self, scene: Scene, frames: range) -> None:
        self.scene, self.frames = scene, iter(frames)

    def detect(self, frames):
        obs = self.scene.observe(next(self.frames))
        hips = obs.joints[:, 11:13].mean(1)
        out = []
        for k, camera in enumerate(self.scene.cameras):
            depth = camera.project_depth(hips)[1]
            boxes = camera_truth(obs.true_boxes[:, k], depth, camera.image_size).boxes
            boxes = boxes[np.isfinite(boxes).all(1)].astype(np.float32)
            out.append(Detections(boxes, np.ones(len(boxes), np.float32)))
        return out


def test_in_view_counts_what_a_perfect_detector_finds(monkeypatch: pytest.MonkeyPatch) -> None:
    scene = Scene(get_config("indoor-2cam"), seed=5)
    monkeypatch.setattr(scene, "render", lambda frame, camera: np.zeros((1, 1, 3), np.uint8))
    frames = range(0, 60, 6)
    cameras = in_view(scene, frames)
    data = detector_dataset(scene, frames, PerfectDetector(scene, frames))
    assert len(cameras) == data.n > 0
    np.testing.assert_array_equal(np.sort(cameras), np.sort(data.visible().sum(1)))
    assert cameras.min() >= 1 and cameras.max() <= scene.num_cameras


def _result(setting: str, found: int, errors: list[float], mean: float) -> SettingResult:
    errs = np.array(errors)
    return SettingResult(
        setting=setting,
        detector="fake",
        in_view=10,
        truth_cameras=np.array([3] * 8 + [2, 1]),
        cameras=np.array([3, 3, 3, 2, 2, 1, 1, 1, 1, 1][:found]),
        errors=errs,
        metrics={"mean": mean, "median": mean / 2, "acc@0.3": 50.0, "acc@0.5": 75.0},
        train_rows=123,
        epochs=45,
        data_seconds=6.0,
        train_seconds=7.0,
    )


def test_report_on_a_tiny_fake_result() -> None:
    fixed = _result("fixed 320x256", 4, [0.1, 0.2, 0.4, 0.9], 0.4)
    grown = _result("max_shrink 3 (640x384)", 8, [0.1] * 7 + [2.0], 0.35)
    text = report(
        [fixed, grown], "python -m bench.detector.highres_localization --test-frames 4", "HDR."
    )
    assert text.startswith("# High-resolution cameras end to end")
    assert "`python -m bench.detector.highres_localization --test-frames 4`" in text
    assert "Machine:" in text and "HDR." in text
    table = text.split("## Runs")[0].splitlines()
    lines = {line.split(" | ")[0]: line for line in table if line.startswith("| ")}
    # fixed: 4 of 10 localized (3 cameras 30 %, 2 cameras 10 %), 3 within 0.5 m of 10 in view
    assert lines["| fixed 320x256"].split(" | ")[2:6] == ["40.0 %", "0.0", "10.0", "30.0"]
    assert lines["| fixed 320x256"].endswith("| **30.0** |")
    assert lines["| max_shrink 3 (640x384)"].endswith("| **70.0** |")
    assert lines["| simulator truth (in view)"].split(" | ")[1:6] == [
        "10", "100.0 %", "10.0", "10.0", "80.0"
    ]  # fmt: skip
    reading = next(line for line in text.splitlines() if line.startswith("**Reading.**"))
    assert "fixed 320x256 finds 40.0 %" in reading and "30.0 % of all instances" in reading
    assert "raises Acc@0.5 over all instances in view by 40.0 points" in reading
    assert "+40.0 points localized" in reading
