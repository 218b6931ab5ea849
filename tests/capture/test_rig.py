"""CameraRig: frame sets of all cameras' newest frames, skew, stale marks, missing cameras."""

from __future__ import annotations

import pytest

from capture import CameraRig, CameraWorker, Frame, FrameSet, VideoFileSource
from tests.capture.fakes import FaultySource, wait_until, write_mjpg


def test_frame_set_from_two_mjpg_cameras(tmp_path):
    sources = [
        VideoFileSource(write_mjpg(tmp_path / "a.avi"), fps=60.0),
        VideoFileSource(write_mjpg(tmp_path / "b.avi", size=(320, 240)), fps=25.0),
    ]
    with CameraRig([CameraWorker(s, camera=k) for k, s in enumerate(sources)]) as rig:
        assert wait_until(lambda: all(s.connected for s in rig.states()))
        first = rig.frame_set()
        assert first is not None and first.available == [0, 1]
        assert [f.camera for f in first.frames] == [0, 1]
        assert first.frames[0].image.shape == (480, 640, 3)
        assert first.frames[1].image.shape == (240, 320, 3)
        times = [f.timestamp for f in first.frames]
        assert first.skew == pytest.approx(max(times) - min(times))
        assert first.timestamp == min(times)
        second = rig.frame_set(after=first, timeout=10.0)
        assert all(n.seq > o.seq for n, o in zip(second.frames, first.frames, strict=True))
        assert [s.name for s in rig.states()] == ["a", "b"]
        assert wait_until(lambda: all(s.fps > 0 for s in rig.states()))


def test_stale_marks_follow_max_skew():
    frames = [Frame(0, None, 100.0, 1), Frame(1, None, 100.2, 7), None]
    rig = CameraRig([_Fixed(f) for f in frames], max_skew=0.05, max_age=1e12)
    frame_set = rig.frame_set()
    assert frame_set.skew == pytest.approx(0.2)
    assert frame_set.stale == [True, False, False]
    assert frame_set.available == [0, 1]


def test_a_dead_camera_drops_out_and_the_rest_continue():
    flaky, steady = FaultySource("flaky"), FaultySource("steady")
    workers = [CameraWorker(flaky, 0), CameraWorker(steady, 1)]
    with CameraRig(workers, max_age=0.3) as rig:
        assert wait_until(lambda: all(s.connected for s in rig.states()))
        flaky.gone.set()
        assert wait_until(lambda: (fs := rig.frame_set()) is not None and fs.frames[0] is None)
        before = rig.frame_set()
        after = rig.frame_set(after=before, timeout=5.0)  # does not wait for the dead camera
        assert after.frames[0] is None and after.frames[1].seq > before.frames[1].seq
        states = rig.states()
        assert not states[0].connected and states[1].connected
        flaky.gone.clear()
        assert wait_until(lambda: rig.frame_set().frames[0] is not None)
        assert rig.states()[0].reconnects == 1


def test_no_frames_yet_gives_none():
    rig = CameraRig([_Fixed(None), _Fixed(None)])
    assert rig.frame_set() is None
    assert isinstance(FrameSet([None], 0.0).available, list)


class _Fixed:
    """A worker stand-in holding one fixed frame (frame-set arithmetic without threads)."""

    def __init__(self, frame):
        self.frame = frame

    def latest(self):
        return self.frame
