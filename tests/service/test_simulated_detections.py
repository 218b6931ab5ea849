"""The demo's simulated detections: the simulator's boxes per rig camera, false positives too."""

from __future__ import annotations

import numpy as np

from capture.synthetic import SyntheticRig
from models.simulate import Scene, load_profile, make_scene
from models.simulate.profile import PROFILE_DIR
from service.detection.simulated import SimulatedDetections, scene_for
from service.settings import SyntheticSettings


def scene() -> Scene:
    return make_scene("indoor-2cam", seed=3, people=2, fps=30)


def test_simulated_detections_are_the_scene_boxes_per_rig_camera() -> None:
    shown = scene()
    rig = SyntheticRig(shown, cameras=[1, 0], render_every=0)
    found = SimulatedDetections(shown, rig.cameras)(rig.produce(40))
    truth = shown.observe(40)
    for k, camera in enumerate([1, 0]):  # rig camera k is scene camera `camera`
        seen = np.concatenate([truth.boxes[:, camera], truth.false_boxes[camera]])
        np.testing.assert_allclose(found[k].boxes, seen[np.isfinite(seen).all(axis=1)])
        # each person's own keypoints ride with their box; false positives have none (NaN)
        people = np.isfinite(truth.boxes[:, camera]).all(axis=1)
        count = int(people.sum())
        points = found[k].keypoints
        assert points is not None
        np.testing.assert_allclose(points[:count], truth.keypoints[people, camera])
        assert np.isnan(points[count:]).all()


def test_simulated_detections_include_the_profiles_false_positives() -> None:
    assert load_profile(PROFILE_DIR / "nanodet.json").false_positives.per_frame > 0
    shown = scene()
    rig = SyntheticRig(shown, render_every=0)
    stage = SimulatedDetections(shown)
    extra = 0
    for i in range(0, 640, 4):
        people = np.isfinite(shown.observe(i).boxes).all(axis=2).sum(axis=0)  # per camera
        extra += sum(len(d) - n for d, n in zip(stage(rig.produce(i)), people, strict=True))
    assert extra > 0  # boxes where nobody is, as from the real detector
    ideal = make_scene("indoor-2cam", seed=3, people=2, detector_profile="ideal")
    assert ideal.profile.name == "ideal"
    assert ideal.observe(5).false_boxes.shape[1] == 0


def test_scene_for_settings_is_reproducible() -> None:
    settings = SyntheticSettings(preset="indoor-2cam", seed=5, people=2, fps=15.0)
    first, second = scene_for(settings), scene_for(settings)
    assert first.fps == 15.0 and first.config.people == 2
    np.testing.assert_array_equal(first.observe(33).world, second.observe(33).world)
