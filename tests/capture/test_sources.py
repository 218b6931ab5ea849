"""Video-file and V4L2 sources through the real OpenCV decoding path (no webcam needed)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from capture import FrameSource, V4L2Source, VideoFileSource
from common.errors import MomlocError
from tests.capture.fakes import FaultySource, frame_number, write_mjpg


def test_video_file_decodes_every_frame_in_order_and_loops(tmp_path):
    source = VideoFileSource(write_mjpg(tmp_path / "cam.avi", frames=12), pace=False)
    assert isinstance(source, FrameSource)
    source.open()
    read = [source.read() for _ in range(30)]
    source.close()
    images = [image for image in read if image is not None]
    assert len(images) == len(read)
    assert all(image.shape == (480, 640, 3) and image.dtype == np.uint8 for image in images)
    assert [frame_number(image) for image in images] == [i % 12 for i in range(30)]
    assert source.fps == 30.0 and source.last_seq == 29


def test_video_file_without_loop_ends_with_none(tmp_path):
    source = VideoFileSource(write_mjpg(tmp_path / "cam.avi", frames=3), loop=False, pace=False)
    source.open()
    assert [frame_number(_read(source)) for _ in range(3)] == [0, 1, 2]
    assert source.read() is None
    source.close()
    source.close()  # idempotent


def test_video_file_is_paced_to_real_time(tmp_path):
    source = VideoFileSource(write_mjpg(tmp_path / "cam.avi", frames=12), fps=50.0)
    source.open()
    start = time.monotonic()
    for _ in range(11):
        source.read()
    elapsed = time.monotonic() - start
    source.close()
    assert elapsed >= 10 / 50.0 - 0.005  # never faster than the frame rate (lower bound only)


def test_file_errors_are_one_line(tmp_path):
    with pytest.raises(MomlocError, match="not found"):
        VideoFileSource(tmp_path / "absent.avi").open()
    garbage = tmp_path / "garbage.avi"
    garbage.write_bytes(b"this is not a video" * 100)
    source = VideoFileSource(garbage)
    with pytest.raises(MomlocError, match="cannot be opened"):
        source.open()
    assert source.read() is None


def test_v4l2_source_reports_missing_devices(tmp_path):
    with pytest.raises(MomlocError, match="no such device"):
        V4L2Source(str(tmp_path / "video9")).open()
    source = V4L2Source(63)  # this machine (and CI) has no /dev/video63
    with pytest.raises(MomlocError, match="/dev/video63: no such device"):
        source.open()
    not_a_camera = tmp_path / "video0"
    not_a_camera.write_bytes(b"")
    with pytest.raises(MomlocError, match="cannot open with V4L2"):
        V4L2Source(str(not_a_camera)).open()
    assert source.read() is None and source.name == "video63"


def test_sources_keep_the_frame_source_protocol(tmp_path):
    assert isinstance(V4L2Source(0), FrameSource)
    assert isinstance(VideoFileSource(tmp_path / "a.avi"), FrameSource)
    assert isinstance(FaultySource(), FrameSource)


def _truncated(tmp_path, frames: int = 60, keep: float = 0.3):
    whole = write_mjpg(tmp_path / "whole.avi", frames=frames)
    cut = tmp_path / "cut.avi"
    data = whole.read_bytes()
    cut.write_bytes(data[: int(len(data) * keep)])
    return cut


def test_truncated_video_file_is_a_dead_camera_not_a_loop(tmp_path):
    """Issue 12, defect 7: a cut file used to replay its few decodable frames for ever."""
    source = VideoFileSource(_truncated(tmp_path), pace=False)
    source.open()
    decoded = 0
    with pytest.raises(MomlocError, match=r"truncated or corrupt, only \d+ of 60 frames"):
        for _ in range(200):
            assert source.read() is not None
            decoded += 1
    assert 0 < decoded < 60
    source.close()
    with pytest.raises(MomlocError, match="truncated or corrupt"):
        source.open()  # the same damaged file stays refused


def test_truncated_video_file_is_reported_disconnected(tmp_path):
    from capture.worker import CameraWorker

    worker = CameraWorker(VideoFileSource(_truncated(tmp_path), fps=30.0), camera=0)
    worker.start()
    try:
        deadline = time.monotonic() + 20
        while (state := worker.state()).error is None or state.connected:
            assert time.monotonic() < deadline, state
            time.sleep(0.05)
        time.sleep(1.0)  # a second later: still dead (it used to reconnect and replay)
        state = worker.state()
        assert not state.connected and "truncated or corrupt" in (state.error or ""), state
    finally:
        worker.stop()


def test_repaired_video_file_is_played_again(tmp_path):
    cut = _truncated(tmp_path)
    source = VideoFileSource(cut, pace=False)
    source.open()
    with pytest.raises(MomlocError):
        for _ in range(200):
            source.read()
    write_mjpg(cut, frames=12)  # the file is replaced by a whole one
    source.open()
    assert [frame_number(_read(source)) for _ in range(14)] == [*range(12), 0, 1]


def _read(source: VideoFileSource) -> np.ndarray:
    """The next image, which the test knows is there."""
    image = source.read()
    assert image is not None
    return image
