"""Synthetic cameras: lock-step frames, exact scene-frame lookup, worker-compatible source."""

from __future__ import annotations

import numpy as np

from capture.rig import FrameSet
from capture.synthetic import SceneClock, SyntheticRig, SyntheticSource
from capture.worker import CameraWorker, Frame
from models.simulate import make_scene


def scene():
    return make_scene("indoor-2cam", seed=3, people=2, fps=30)


def test_rig_frames_are_lock_step_and_stamps_name_their_scene_frame():
    rig = SyntheticRig(scene(), fps=30, render_every=2)
    first, second = rig.produce(10), rig.produce(11)
    (a, b), (c, _) = _both(first), _both(second)
    assert [a.seq, b.seq] == [10, 10] and first.skew == 0.0
    assert a.timestamp == b.timestamp
    assert a.image is not None and a.image.shape == (480, 640, 3)
    assert c.image is None  # render_every=2: odd frames carry no pixels
    assert b.image is not None
    np.testing.assert_array_equal(b.image, rig.scene.render(10, 1))
    assert rig.index_at(a.timestamp) == 10
    assert rig.index_at(c.timestamp) == 11


def test_rig_thread_publishes_newer_sets_and_reports_state():
    rig = SyntheticRig(scene(), fps=30, render_every=0)
    rig.start()
    try:
        first = rig.frame_set(after=None)
        while first is None:
            first = rig.frame_set()
        newer = rig.frame_set(after=first, timeout=2.0)
        assert newer is not None and newer is not first
        assert _both(newer)[0].seq > _both(first)[0].seq
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
        assert frame is not None and frame.image is not None
        assert frame.image.shape == (480, 640, 3)
        image = frame.image
        newest = source.last_index
        assert newest is not None
        recent = range(max(0, newest - 30), newest + 1)  # the worker may have read on since
        assert any(np.array_equal(image, clock.render(i, 1)) for i in recent)
    finally:
        worker.stop()


def _both(frame_set: FrameSet) -> tuple[Frame, Frame]:
    """The two cameras' frames of a synthetic set (every camera delivers)."""
    a, b = frame_set.frames
    assert a is not None and b is not None
    return a, b
