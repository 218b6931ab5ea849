"""The recording format (capture/recording.py) and its replay as a camera (capture/replay.py)."""

from __future__ import annotations

import json
import re
import time

import numpy as np
import pytest

from capture.recording import Recording, RecordingWriter
from capture.replay import RecordedSource, open_file_source
from capture.rig import FrameSet
from capture.sources import VideoFileSource
from capture.worker import Frame
from common.errors import MomlocError


def image(value: int, size=(64, 48)) -> np.ndarray:
    """A flat grey image (survives MJPG with a small error) with a bright block at ``value``."""
    out = np.full((size[1], size[0], 3), 40, np.uint8)
    out[8:24, value : value + 8] = 220
    return out


def frames(t: float, seqs, values) -> FrameSet:
    made = [
        None if s is None else Frame(k, image(v), t + 0.01 * k, s)
        for k, (s, v) in enumerate(zip(seqs, values, strict=True))
    ]
    return FrameSet(made, skew=0.0)


def write_sample(folder):
    """Camera 1 repeats its frame in set 1 and has none in set 2; camera 0 drops seq 3."""
    with RecordingWriter(folder, ["left", "right"], fps=10) as writer:
        writer.add(frames(100.0, [1, 1], [4, 10]))
        writer.add(frames(100.1, [2, 1], [12, 10]))
        writer.add(frames(100.2, [4, None], [20, 0]))
    return folder


def test_frame_sets_come_back_as_recorded(tmp_path):
    recording = Recording.open(write_sample(tmp_path / "rec"))
    assert len(recording) == 3 and recording.num_cameras == 2
    assert recording.image_sizes == [(64, 48), (64, 48)]
    assert [c.frames for c in recording.cameras] == [3, 1]  # the repeat is stored once
    sets = list(recording.frame_sets())
    assert [i for i, _ in sets] == [0, 1, 2]
    seqs = [[None if f is None else f.seq for f in s.frames] for _, s in sets]
    assert seqs == [[1, 1], [2, 1], [4, None]]
    stamps = [[None if f is None else round(f.timestamp, 6) for f in s.frames] for _, s in sets]
    assert stamps == [[100.0, 100.01], [100.1, 100.01], [100.2, None]]
    assert sets[1][1].skew == pytest.approx(0.09) and sets[1][1].stale == [False, True]
    # the right pixels: the bright block sits where it was drawn
    first = sets[1][1].frames[0]
    assert first is not None and first.image is not None
    left = first.image
    assert left.shape == (48, 64, 3) and left[16, 14, 0] > 150 and left[16, 4, 0] < 100
    manifest = json.loads((tmp_path / "rec" / "manifest.json").read_text())
    assert manifest["format"] == "momloc-recording" and manifest["version"] == 1
    assert [c["name"] for c in manifest["cameras"]] == ["left", "right"]


def test_unfinished_or_foreign_folders_are_refused(tmp_path):
    folder = write_sample(tmp_path / "rec")
    with pytest.raises(MomlocError, match="exists and is not an empty folder"):
        RecordingWriter(folder, ["a"])
    (folder / "manifest.json").unlink()
    with pytest.raises(MomlocError, match=re.escape("no manifest.json")):
        Recording.open(folder)
    with pytest.raises(MomlocError, match="no such recording folder"):
        Recording.open(tmp_path / "missing")


def test_truncated_video_is_an_error_not_a_short_recording(tmp_path):
    folder = write_sample(tmp_path / "rec")
    video = folder / "cam0.avi"
    video.write_bytes(video.read_bytes()[: video.stat().st_size // 2])
    with pytest.raises(MomlocError, match=re.escape("cam0.avi")):
        list(Recording.open(folder).frame_sets())


def test_replay_keeps_the_recorded_intervals(tmp_path):
    """Frames are never delivered before their recorded offset (a loaded machine may deliver
    late, never early): irregular gaps survive, unlike a fixed-rate video reader."""
    offsets = [0.0, 0.05, 0.35, 0.4]
    with RecordingWriter(tmp_path / "rec", ["cam"], fps=20) as writer:
        for i, dt in enumerate(offsets):
            writer.add(FrameSet([Frame(0, image(4 * i), 50.0 + dt, i)], skew=0.0))
    source = open_file_source(tmp_path / "rec" / "cam0.avi", loop=False)
    assert isinstance(source, RecordedSource)
    source.open()
    start = time.monotonic()
    delivered = []
    while (picture := source.read()) is not None:
        delivered.append(time.monotonic() - start)
        assert picture.shape == (48, 64, 3)
    source.close()
    assert len(delivered) == len(offsets)
    assert all(got >= want - 0.005 for got, want in zip(delivered, offsets, strict=True))
    assert delivered[2] - delivered[0] >= 0.3 - 0.005  # the long gap is kept
    # looping starts over one mean interval after the end: frame 0 again at 0.4 + 0.4 / 3 s
    looping = open_file_source(tmp_path / "rec", camera=0)
    looping.open()
    start = time.monotonic()
    for _ in range(len(offsets) + 1):
        assert looping.read() is not None
    assert time.monotonic() - start >= 0.4 + 0.4 / 3 - 0.005
    looping.close()


def test_file_camera_kinds(tmp_path):
    folder = write_sample(tmp_path / "rec")
    chosen = open_file_source(folder, camera=1)
    assert isinstance(chosen, RecordedSource) and chosen.name == "right"
    with pytest.raises(MomlocError, match=re.escape("give camera: 0..1")):
        open_file_source(folder)
    plain = tmp_path / "plain.avi"
    plain.write_bytes((folder / "cam0.avi").read_bytes())
    assert isinstance(open_file_source(plain), VideoFileSource)
    with pytest.raises(MomlocError, match=re.escape("camera: 1 is only for a recording folder")):
        open_file_source(plain, camera=1)
    # a fixed fps asks for the plain reader even when timestamps are there
    assert isinstance(open_file_source(folder / "cam0.avi", fps=5), VideoFileSource)
