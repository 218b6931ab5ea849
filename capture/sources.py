"""Frame sources: where one camera's frames come from (V4L2 webcam, video file; synthetic lives
in ``capture.synthetic``).

The contract every source keeps, so one :class:`~capture.worker.CameraWorker` drives them all:

- ``open()`` connects (raises :class:`~common.errors.MomlocError` with one line if it cannot);
  ``close()`` releases everything and may be called twice; ``open()`` after ``close()`` reconnects.
- ``read()`` blocks until the next frame and returns it as uint8 BGR [H, W, 3], or ``None`` when
  no frame came (device gone, stream ended, read timeout). It must return within a bounded time,
  so the worker can notice a dead camera and reopen it; it may raise on errors.
- ``name`` labels logs and ``momloc cameras``; ``fps`` (nominal, optional) sets the watchdog's
  expectation before the real rate has been measured.
- Optional ``last_timestamp`` (wall-clock time the last frame was captured, before decoding) and
  ``last_seq`` (the source's own frame number) refine what the worker stamps on the frame.

Sources are not thread-safe: exactly one worker thread calls them.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

import cv2
import numpy as np

from common.errors import MomlocError


@runtime_checkable
class FrameSource(Protocol):
    """One camera's frames; see the module docstring for the contract."""

    name: str

    def open(self) -> None: ...

    def read(self) -> np.ndarray | None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class Negotiated:
    """What the driver granted when asked for a format (it may differ from what was asked)."""

    fourcc: str
    width: int
    height: int
    fps: float


class V4L2Source:
    """A USB webcam through OpenCV's V4L2 backend: MJPG, 640×480, 30 fps, one-frame buffer.

    MJPG because two or more cameras at 640×480×30 exceed USB 2 bandwidth in raw YUYV; the
    one-frame driver buffer (``CAP_PROP_BUFFERSIZE`` 1) keeps the frame we get the newest one.
    ``device`` is an index, ``/dev/videoN`` or, better for rigs, a stable
    ``/dev/v4l/by-id/...`` path (indices can change when a camera is replugged).
    Reads time out after ``read_timeout`` seconds so a camera that stops delivering makes
    ``read()`` return None (and the worker reopen it) instead of blocking: OpenCV's V4L2 backend
    ignores ``CAP_PROP_READ_TIMEOUT_MSEC`` and waits ``OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT`` whole
    seconds (default 10), read once per process, so we set that variable (if unset) before the
    first capture opens.
    """

    def __init__(
        self,
        device: int | str = 0,
        width: int = 640,
        height: int = 480,
        fps: float = 30.0,
        fourcc: str = "MJPG",
        read_timeout: float = 1.0,
    ) -> None:
        self.device = device
        self.width, self.height, self.fps = int(width), int(height), float(fps)
        self.fourcc = fourcc
        self.read_timeout = float(read_timeout)
        self.name = f"video{device}" if isinstance(device, int) else Path(device).name
        self.last_timestamp: float | None = None
        self.negotiated: Negotiated | None = None  # set by open()
        self._capture: cv2.VideoCapture | None = None

    def open(self) -> None:
        self.close()
        target = self.device if isinstance(self.device, int) else str(self.device)
        path = f"/dev/video{target}" if isinstance(target, int) else target
        if not os.path.exists(path):  # checked first: OpenCV would log a warning per retry
            raise MomlocError(f"camera {path}: no such device (unplugged?)")
        # OpenCV reads this when the capture is created; default 10 s is far too long.
        os.environ.setdefault(
            "OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT", str(max(1, round(self.read_timeout)))
        )
        capture = cv2.VideoCapture(target, cv2.CAP_V4L2)
        if not capture.isOpened():
            capture.release()
            raise MomlocError(f"camera {self.device}: cannot open with V4L2 (busy or unplugged?)")
        # FOURCC first: some drivers reset the size when the pixel format changes.
        capture.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*self.fourcc))
        capture.set(cv2.CAP_PROP_FRAME_WIDTH, self.width)
        capture.set(cv2.CAP_PROP_FRAME_HEIGHT, self.height)
        capture.set(cv2.CAP_PROP_FPS, self.fps)
        capture.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        code = int(capture.get(cv2.CAP_PROP_FOURCC))
        self.negotiated = Negotiated(
            fourcc="".join(chr((code >> (8 * i)) & 0xFF) for i in range(4)),
            width=int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)),
            height=int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)),
            fps=float(capture.get(cv2.CAP_PROP_FPS)),
        )
        self._capture = capture

    def read(self) -> np.ndarray | None:
        if self._capture is None:
            return None
        # grab() returns when the driver hands over a buffer: that is the capture moment;
        # retrieve() then decodes the MJPG, which must not count as latency of the camera.
        if not self._capture.grab():
            return None
        self.last_timestamp = time.time()
        ok, image = self._capture.retrieve()
        return image if ok else None

    def close(self) -> None:
        if self._capture is not None:
            self._capture.release()
            self._capture = None


class VideoFileSource:
    """A recorded video played as if it were a live camera: paced to real time and looping.

    Pacing follows the file's frame rate (or ``fps``); when the reader falls behind by more than
    a frame the schedule restarts instead of bursting, like a real camera that drops frames.
    ``pace=False`` reads as fast as decoding allows (benchmarks, batch processing).

    A truncated or corrupt file is a dead camera, not a healthy one: when decoding stops well
    before the frame count the container declares, ``read()`` raises and ``open()`` refuses the
    same file (same size and modification time) from then on. Looping would otherwise replay the
    few frames that decode for ever, and ``/v1/health`` would show a connected camera.
    """

    def __init__(
        self, path: str | Path, fps: float | None = None, loop: bool = True, pace: bool = True
    ) -> None:
        self.path = Path(path)
        self.name = self.path.stem
        self.loop, self.pace = loop, pace
        self._requested_fps = fps
        self.fps = float(fps) if fps else 30.0
        self.last_timestamp: float | None = None
        self.last_seq: int | None = None
        self._capture: cv2.VideoCapture | None = None
        self._index = 0
        self._start = 0.0
        self._declared = 0  # frame count in the container header (0: unknown)
        self._in_pass = 0  # frames decoded since the last rewind
        self._broken: tuple[tuple[int, int], str] | None = None  # (file identity, message)

    def _identity(self) -> tuple[int, int]:
        stat = self.path.stat()
        return stat.st_size, stat.st_mtime_ns

    def open(self) -> None:
        self.close()
        if not self.path.is_file():
            raise MomlocError(f"video file {self.path}: not found")
        if self._broken is not None and self._broken[0] == self._identity():
            raise MomlocError(self._broken[1])  # the same damaged file: still dead
        capture = cv2.VideoCapture(str(self.path))
        if not capture.isOpened():
            capture.release()
            raise MomlocError(f"video file {self.path}: cannot be opened as video")
        file_fps = capture.get(cv2.CAP_PROP_FPS)
        if not self._requested_fps and file_fps and 1.0 <= file_fps <= 240.0:
            self.fps = float(file_fps)
        self._capture = capture
        self._index, self._start = 0, time.monotonic()
        self._declared = max(int(capture.get(cv2.CAP_PROP_FRAME_COUNT) or 0), 0)
        self._in_pass = 0

    def read(self) -> np.ndarray | None:
        if self._capture is None:
            return None
        if self.pace:
            due = self._start + self._index / self.fps
            wait = due - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            elif wait < -1.0 / self.fps:  # fell behind: restart the schedule, no burst
                self._start = time.monotonic() - self._index / self.fps
        ok, image = self._capture.read()
        if not ok:
            self._check_complete()
        if not ok and self.loop and self._in_pass > 0:
            self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
            self._in_pass = 0
            ok, image = self._capture.read()
        if not ok:
            return None
        self.last_timestamp = time.time()
        self.last_seq = self._index
        self._index += 1
        self._in_pass += 1
        return image

    def _check_complete(self) -> None:
        """Decoding stopped: fine at the declared end, a damaged file before it."""
        missing = self._declared - self._in_pass
        if self._declared <= 0 or missing <= max(2, 0.02 * self._declared):
            return
        message = (
            f"video file {self.path}: truncated or corrupt, only {self._in_pass} of "
            f"{self._declared} frames decode"
        )
        self._broken = (self._identity(), message)
        raise MomlocError(message)

    def close(self) -> None:
        if self._capture is not None:
            self._capture.release()
            self._capture = None
