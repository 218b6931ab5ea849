"""One reader thread per camera: newest-frame slot, timestamps, watchdog and reconnect.

Why a thread per camera: ``read()`` blocks until the camera delivers, and cameras are not in
lock-step; a thread each lets every camera run at its own pace and the pipeline take whatever is
newest. Policies, in one place:

- **Newest frame only.** The worker keeps a single slot; a new frame replaces the old one. A slow
  consumer therefore skips frames and never makes the worker queue them (no growing latency).
- **Timestamps** are wall-clock (``clock.time()``) at capture: the source's ``last_timestamp`` if
  it has one (V4L2 stamps after ``grab()``, before MJPG decoding), else when ``read()`` returned.
- **Watchdog.** The expected frame interval is measured (nominal ``source.fps`` until enough
  frames came). A camera with no frame for ``stall_intervals`` (2) intervals (but at least
  ``min_stall`` = 50 ms, so a 60 fps camera is not flagged by scheduling jitter) is reported
  stalled at once by :meth:`CameraWorker.state` and counted by the watchdog thread. Being
  flagged does not by itself reopen the camera: a late frame is still a good frame.
- **Reconnect with back-off.** When ``read()`` returns ``None`` or raises (device unplugged,
  stream over, read timeout), the worker closes the source and reopens it: first at once, then
  after ``backoff`` seconds doubling up to ``max_backoff`` until a frame arrives again (a camera
  that opens but never streams is also retried with back-off). A failing
  camera never touches the other cameras' workers.
- **Time is injected** (``clock``, a :class:`Clock`): the wall clock for timestamps, ages and the
  measured rate, and the waits of the back-off and the watchdog. :class:`SystemClock` is the real
  one; a test gives a clock it advances itself, so how many reconnects happen in a second of
  back-off is a fact of the policy, not of the machine's load (as ``DetectionScheduler``'s clock).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from capture.sources import FrameSource

FPS_WINDOW = 2.0  # seconds of timestamps the measured frame rate averages over


class Clock(Protocol):
    """Where a worker's time comes from."""

    def time(self) -> float:
        """Wall-clock seconds (frame timestamps are compared across cameras and processes)."""
        ...

    def wait(self, stop: threading.Event, seconds: float) -> bool:
        """Wait ``seconds`` or until ``stop`` is set; whether it was set."""
        ...


class SystemClock:
    """The real clock: ``time.time`` and ``Event.wait``."""

    def time(self) -> float:
        return time.time()

    def wait(self, stop: threading.Event, seconds: float) -> bool:
        return stop.wait(seconds)


@dataclass(frozen=True)
class Frame:
    """One captured image. ``timestamp`` is wall-clock capture time; ``seq`` counts frames."""

    camera: int
    image: np.ndarray | None
    timestamp: float
    seq: int


@dataclass(frozen=True)
class CameraState:
    """Health of one camera, for ``/v1/health``, metrics and logs."""

    connected: bool
    fps: float
    last_frame_age: float | None
    reconnects: int
    error: str | None
    name: str = ""
    frames: int = 0
    stalls: int = 0


class CameraWorker:
    """Reads one :class:`FrameSource` in its own thread and keeps only the newest frame.

    Example::

        worker = CameraWorker(V4L2Source("/dev/video0"), camera=0)
        worker.start()
        frame = worker.wait_for_frame(timeout=2.0)
        worker.state().fps
        worker.stop()
    """

    def __init__(
        self,
        source: FrameSource,
        camera: int = 0,
        *,
        stall_intervals: float = 2.0,
        min_stall: float = 0.05,
        backoff: float = 0.1,
        max_backoff: float = 1.0,
        clock: Clock | None = None,
    ) -> None:
        self.source = source
        self.clock: Clock = SystemClock() if clock is None else clock
        self.camera = int(camera)
        self.name = getattr(source, "name", f"camera{camera}")
        self.stall_intervals, self.min_stall = float(stall_intervals), float(min_stall)
        self.backoff, self.max_backoff = float(backoff), float(max_backoff)
        nominal = float(getattr(source, "fps", 0.0) or 30.0)
        self._nominal_interval = 1.0 / nominal
        self._cond = threading.Condition()
        self._latest: Frame | None = None
        self._stamps: deque[float] = deque(maxlen=240)
        self._seq = 0
        self._open = False
        self._ever_open = False
        self._reconnects = 0
        self._stalls = 0
        self._stalled = False
        self._error: str | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    # -- public -----------------------------------------------------------------------------

    def start(self) -> None:
        if self._threads:
            return
        self._stop.clear()
        self._threads = [
            threading.Thread(target=self._run, name=f"capture-{self.name}", daemon=True),
            threading.Thread(target=self._watch, name=f"watchdog-{self.name}", daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        for thread in self._threads:
            thread.join(timeout)
        self._threads = []
        self._close()

    def latest(self) -> Frame | None:
        """The newest frame (or None before the first); never blocks."""
        return self._latest

    def wait_for_frame(self, after_seq: int = -1, timeout: float | None = None) -> Frame | None:
        """Block until a frame newer than ``after_seq`` exists (the newest one is returned) or
        ``timeout`` passes (None returned)."""
        with self._cond:
            self._cond.wait_for(
                lambda: (
                    self._stop.is_set()
                    or (self._latest is not None and self._latest.seq > after_seq)
                ),
                timeout,
            )
            frame = self._latest
        return frame if frame is not None and frame.seq > after_seq else None

    def frame_interval(self, fps: float | None = None) -> float:
        """Expected seconds between frames: measured when possible, else the nominal rate."""
        fps = self._measured_fps() if fps is None else fps
        return 1.0 / fps if fps > 0 else self._nominal_interval

    def stall_timeout(self, fps: float | None = None) -> float:
        """Seconds without a frame after which the camera counts as stalled."""
        return max(self.stall_intervals * self.frame_interval(fps), self.min_stall)

    def state(self) -> CameraState:
        now = self.clock.time()
        frame = self._latest
        fps = self._measured_fps(now)
        age = now - frame.timestamp if frame is not None else None
        fresh = age is not None and age <= self.stall_timeout(fps)
        error = self._error
        if self._open and age is not None and not fresh:
            error = f"stalled: no frame for {age * 1000:.0f} ms"
        return CameraState(
            connected=self._open and fresh,
            fps=fps,
            last_frame_age=age,
            reconnects=self._reconnects,
            error=None if (self._open and fresh) else error,
            name=self.name,
            frames=self._seq,
            stalls=self._stalls,
        )

    # -- threads ----------------------------------------------------------------------------

    def _run(self) -> None:
        delay = 0.0
        while not self._stop.is_set():
            if not self._open:
                if delay and self.clock.wait(self._stop, delay):
                    break
                self._try_open()
                # Grows until a frame arrives, so a camera that opens but never streams is
                # retried with back-off too, not in a busy loop.
                delay = min(max(delay * 2, self.backoff), self.max_backoff)
                continue
            try:
                image = self.source.read()
            except Exception as error:  # any source failure: record, reopen
                self._lost(f"read failed: {_one_line(error)}")
                continue
            if image is None:
                self._lost("no frame (camera gone, stream ended or read timed out)")
                continue
            self._publish(image)
            delay = 0.0

    def _watch(self) -> None:
        """Counts stalls as they happen (state() reports them itself, at query time)."""
        while not self.clock.wait(self._stop, min(self.frame_interval() / 2, 0.05)):
            frame = self._latest
            if frame is None or not self._open:
                continue
            stalled = self.clock.time() - frame.timestamp > self.stall_timeout()
            if stalled and not self._stalled:
                self._stalls += 1
            self._stalled = stalled

    # -- helpers ----------------------------------------------------------------------------

    def _try_open(self) -> bool:
        try:
            self.source.open()
        except Exception as error:
            self._error = f"open failed: {_one_line(error)}"
            return False
        if self._ever_open:
            self._reconnects += 1
        self._ever_open = True
        self._open = True
        return True

    def _lost(self, reason: str) -> None:
        self._error = reason
        self._close()

    def _close(self) -> None:
        self._open = False
        try:
            self.source.close()
        except Exception as error:
            self._error = f"close failed: {_one_line(error)}"

    def _publish(self, image: np.ndarray) -> None:
        stamp = getattr(self.source, "last_timestamp", None)
        timestamp = float(stamp) if stamp is not None else self.clock.time()
        with self._cond:
            frame = Frame(self.camera, image, timestamp, self._seq)
            self._seq += 1
            self._latest = frame
            self._stamps.append(timestamp)
            self._error = None
            self._cond.notify_all()

    def _measured_fps(self, now: float | None = None) -> float:
        now = self.clock.time() if now is None else now
        with self._cond:
            stamps = list(self._stamps)
        recent = [t for t in stamps if now - t <= FPS_WINDOW]
        if len(recent) < 3:
            return 0.0
        span = recent[-1] - recent[0]
        return (len(recent) - 1) / span if span > 0 else 0.0


def _one_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0]}" if text else type(error).__name__
