"""Synthetic cameras: lock-step frames, exact ground truth lookup, worker-compatible source."""

from __future__ import annotations

import numpy as np

from capture.synthetic import (
    SceneClock,
    SimulatedDetections,
    SyntheticRig,
    SyntheticSource,
    make_scene,
)
from capture.worker import CameraWorker


def scene():
    return make_scene("indoor-2cam", seed=3, people=2, fps=30)


def test_rig_frames_are_lock_step_and_ground_truth_is_exact():
    rig = SyntheticRig(scene(), fps=30, render_every=2)
    first, second = rig.produce(10), rig.produce(11)
    assert [f.seq for f in first.frames] == [10, 10] and first.skew == 0.0
    assert first.frames[0].timestamp == first.frames[1].timestamp
    assert first.frames[0].image.shape == (480, 640, 3)
    assert second.frames[0].image is None  # render_every=2: odd frames carry no pixels
    np.testing.assert_array_equal(first.frames[1].image, rig.scene.render(10, 1))
    truth = rig.observation_at(first.frames[0].timestamp)
    assert truth.frame == 10
    np.testing.assert_array_equal(truth.world, rig.scene.observe(10).world)


def test_simulated_detections_are_the_scene_boxes_per_camera():
    rig = SyntheticRig(scene(), cameras=[1, 0], render_every=0)
    frame_set = rig.produce(40)
    found = SimulatedDetections(rig)(frame_set)
    truth = rig.scene.observe(40)
    for k, camera in enumerate([1, 0]):  # rig camera k is scene camera `camera`
        seen = np.concatenate([truth.boxes[:, camera], truth.false_boxes[camera]])
        np.testing.assert_allclose(found[k].boxes, seen[np.isfinite(seen).all(axis=1)])
        # each person's own keypoints ride with their box; false positives have none (NaN)
        people = np.isfinite(truth.boxes[:, camera]).all(axis=1)
        count = int(people.sum())
        np.testing.assert_allclose(found[k].keypoints[:count], truth.keypoints[people, camera])
        assert np.isnan(found[k].keypoints[count:]).all()


def test_simulated_detections_include_the_profiles_false_positives():
    from models.simulate import load_profile
    from models.simulate.profile import PROFILE_DIR

    assert load_profile(PROFILE_DIR / "nanodet.json").false_positives.per_frame > 0
    rig = SyntheticRig(make_scene("indoor-2cam", seed=3, people=2, fps=30), render_every=0)
    stage = SimulatedDetections(rig)
    extra = 0
    for i in range(0, 640, 4):
        truth = rig.observation(i)
        people = np.isfinite(truth.boxes).all(axis=2).sum(axis=0)  # per camera
        extra += sum(len(d) - n for d, n in zip(stage(rig.produce(i)), people, strict=True))
    assert extra > 0  # boxes where nobody is, as from the real detector
    ideal = SyntheticRig(make_scene("indoor-2cam", seed=3, people=2, detector_profile="ideal"))
    assert ideal.scene.profile.name == "ideal"
    assert ideal.observation(5).false_boxes.shape[1] == 0


def test_rig_thread_publishes_newer_sets_and_reports_state():
    rig = SyntheticRig(scene(), fps=30, render_every=0)
    rig.start()
    try:
        first = rig.frame_set(after=None)
        while first is None:
            first = rig.frame_set()
        newer = rig.frame_set(after=first, timeout=2.0)
        assert newer is not first and newer.frames[0].seq > first.frames[0].seq
        states = rig.states()
        assert len(states) == 2 and all(s.connected for s in states)
    finally:
        rig.stop()
    assert not any(s.connected for s in rig.states())


def test_source_runs_under_a_camera_worker():
    clock = SceneClock(scene(), fps=30)
    source = SyntheticSource(clock, 1)
    worker = CameraWorker(source, camera=1)
    worker.start()
    try:
        frame = worker.wait_for_frame(timeout=10.0)
        assert frame is not None and frame.image.shape == (480, 640, 3)
        newest = source.last_index
        assert newest is not None
        recent = range(max(0, newest - 30), newest + 1)  # the worker may have read on since
        assert any(np.array_equal(frame.image, clock.render(i, 1)) for i in recent)
    finally:
        worker.stop()
