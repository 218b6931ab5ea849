"""Replay one camera of a recording (:mod:`capture.recording`) as a live camera, with the
recorded timing: frame *i* is delivered ``t_i - t_start`` seconds after the replay started.

Why not :class:`~capture.sources.VideoFileSource` at the container's rate: webcams jitter and
drop frames, and the tracker's velocities, time-outs and the association's skew rules must see
the intervals that really happened. All cameras of one recording count from the *recording's*
start (``manifest.json``'s ``start``, else the camera's first frame), so cameras opened together
keep their recorded offsets to each other, also when looping (one period for all: the
recording's span plus one mean frame-set interval); a worker opening a few milliseconds later
shifts that camera by as much, which is below a webcam's own jitter.

Frames are stamped with the wall-clock time they are delivered (like a live camera), so latency
and health read as live. Falling more than ``MAX_LAG_S`` behind (a loaded machine) restarts the
schedule from the current frame instead of bursting, as a real camera drops frames. With
``loop`` the recording starts over one mean frame interval after its last frame.

:func:`open_file_source` chooses the source for a ``type: file`` camera: a recording's camera
video (its ``.csv`` timestamps beside it) or a recording folder plus camera index → this
replay; any other video file → ``VideoFileSource`` at the file's frame rate.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import cv2
import numpy as np

from capture.recording import MANIFEST, Recording, read_timestamps, timestamps_path
from capture.sources import FrameSource, VideoFileSource
from common.errors import MomlocError

MAX_LAG_S = 0.5


class RecordedSource:
    """``FrameSource`` replaying ``video`` at the times in its timestamps file."""

    def __init__(self, video: str | Path, *, loop: bool = True, name: str | None = None) -> None:
        self.video = Path(video)
        self.loop = loop
        self.name = name or self.video.stem
        self.times, self.seqs = read_timestamps(timestamps_path(self.video))
        if not len(self.times):
            raise MomlocError(f"{self.video}: the recording has no frames of this camera")
        self.t_start, t_end, sets = _recording_span(self.video.parent, self.times)
        interval = (t_end - self.t_start) / (sets - 1) if sets > 1 else 1 / 30
        self.fps = 1.0 / interval if interval > 0 else 30.0
        # one pass, for looping: the same for every camera of the recording, so they stay in step
        self.period = t_end - self.t_start + interval
        self.last_timestamp: float | None = None
        self.last_seq: int | None = None
        self._capture: cv2.VideoCapture | None = None
        self._index = 0
        self._anchor = 0.0  # monotonic time at which t_start is replayed

    def open(self) -> None:
        self.close()
        capture = cv2.VideoCapture(str(self.video))
        if not capture.isOpened():
            capture.release()
            raise MomlocError(f"recording {self.video}: cannot be opened as video")
        self._capture, self._index, self._anchor = capture, 0, time.monotonic()

    def read(self) -> np.ndarray | None:
        if self._capture is None:
            return None
        if self._index >= len(self.times):
            if not self.loop:
                return None
            self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
            self._index, self._anchor = 0, self._anchor + self.period
        due = self._anchor + float(self.times[self._index]) - self.t_start
        wait = due - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        elif wait < -MAX_LAG_S:  # fell behind: this frame becomes "now", no burst
            self._anchor -= wait
        ok, image = self._capture.read()
        if not ok:
            raise MomlocError(f"recording {self.video}: image {self._index} does not decode")
        self.last_timestamp = time.time()
        self.last_seq = int(self.seqs[self._index])
        self._index += 1
        return image

    def close(self) -> None:
        if self._capture is not None:
            self._capture.release()
            self._capture = None


def _recording_span(folder: Path, times: np.ndarray) -> tuple[float, float, int]:
    """Start and end time and frame-set count of the whole recording (from its manifest), or of
    this camera's frames when the video was copied out of its folder."""
    own = float(times[0]), float(times[-1]), len(times)
    try:
        meta = json.loads((folder / MANIFEST).read_text())
        span = float(meta["start"]), float(meta["end"]), int(meta["frame_sets"])
    except (OSError, ValueError, TypeError, KeyError):
        return own
    return span if span[0] <= own[0] and span[1] >= own[1] else own


def open_file_source(
    path: Path, *, camera: int | None = None, fps: float | None = None, loop: bool = True
) -> FrameSource:
    """The source of a ``type: file`` camera (see the module docstring); ``fps`` given means
    "play at this fixed rate" and so always uses the plain video reader."""
    if path.is_dir():
        recording = Recording.open(path)
        if camera is None or not 0 <= camera < recording.num_cameras:
            raise MomlocError(
                f"cameras: {path} is a recording of {recording.num_cameras} cameras; "
                f"give camera: 0..{recording.num_cameras - 1}"
            )
        chosen = recording.cameras[camera]
        return RecordedSource(chosen.video, loop=loop, name=chosen.name)
    if camera is not None:
        raise MomlocError(f"cameras: camera: {camera} is only for a recording folder, not {path}")
    if not path.is_file():
        raise MomlocError(f"cameras: video file {path} does not exist")
    if fps is None and timestamps_path(path).is_file():
        return RecordedSource(path, loop=loop)
    return VideoFileSource(path, fps=fps, loop=loop)
