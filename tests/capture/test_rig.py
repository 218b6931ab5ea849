"""CameraRig: frame sets of all cameras' newest frames, skew, stale marks, missing cameras."""

from __future__ import annotations

import pytest

from capture import CameraRig, CameraWorker, Frame, FrameSet, VideoFileSource
from capture.worker import CameraState
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
        a, b = _both(first)
        assert [a.camera, b.camera] == [0, 1]
        assert a.image is not None and a.image.shape == (480, 640, 3)
        assert b.image is not None and b.image.shape == (240, 320, 3)
        times = [a.timestamp, b.timestamp]
        assert first.skew == pytest.approx(max(times) - min(times))
        assert first.timestamp == min(times)
        second = rig.frame_set(after=first, timeout=10.0)
        assert second is not None
        assert all(n.seq > o.seq for n, o in zip(_both(second), (a, b), strict=True))
        assert [s.name for s in rig.states()] == ["a", "b"]
        assert wait_until(lambda: all(s.fps > 0 for s in rig.states()))


def test_stale_marks_follow_max_skew():
    frames = [Frame(0, None, 100.0, 1), Frame(1, None, 100.2, 7), None]
    rig = CameraRig([_Fixed(f) for f in frames], max_skew=0.05, max_age=1e12)
    frame_set = rig.frame_set()
    assert frame_set is not None and frame_set.skew == pytest.approx(0.2)
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
        assert before is not None and after is not None and after.frames[0] is None
        was, now = before.frames[1], after.frames[1]
        assert was is not None and now is not None and now.seq > was.seq
        states = rig.states()
        assert not states[0].connected and states[1].connected
        flaky.gone.clear()
        assert wait_until(lambda: (fs := rig.frame_set()) is not None and fs.frames[0] is not None)
        assert rig.states()[0].reconnects == 1


def test_no_frames_yet_gives_none():
    rig = CameraRig([_Fixed(None), _Fixed(None)])
    assert rig.frame_set() is None
    assert isinstance(FrameSet([None], 0.0).available, list)


class _Fixed:
    """A worker stand-in holding one fixed frame (frame-set arithmetic without threads)."""

    def __init__(self, frame: Frame | None) -> None:
        self.frame = frame
        self.camera = 0

    def start(self) -> None: ...
    def stop(self) -> None: ...

    def latest(self) -> Frame | None:
        return self.frame

    def wait_for_frame(self, after_seq: int = -1, timeout: float | None = None) -> Frame | None:
        return self.frame

    def state(self) -> CameraState:
        return CameraState(self.frame is not None, 0.0, None, 0, None)


def _both(frame_set: FrameSet) -> tuple[Frame, Frame]:
    """The two cameras' frames of a set in which both delivered."""
    a, b = frame_set.frames
    assert a is not None and b is not None
    return a, b
