"""Test doubles for camera faults, and real MJPG files written with OpenCV."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import cv2
import numpy as np

from common.errors import MomlocError


def write_mjpg(path: Path, frames: int = 12, size=(640, 480), fps: float = 30.0) -> Path:
    """An MJPG AVI whose frame i is a uniform grey of level 10 + 20 * i (readable after JPEG)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), fps, size)
    assert writer.isOpened(), "OpenCV cannot write MJPG AVI here"
    for i in range(frames):
        writer.write(np.full((size[1], size[0], 3), min(10 + 20 * i, 255), np.uint8))
    writer.release()
    return path


def frame_number(image: np.ndarray) -> int:
    return round((float(image.mean()) - 10) / 20)


class FaultySource:
    """A camera at ``fps`` whose faults tests switch on and off from outside.

    - ``paused``: stops delivering; ``read()`` waits up to ``read_timeout`` then returns None,
      like a V4L2 select timeout;
    - ``fail_reads``: the next N reads raise;
    - ``gone``: unplugged: ``read()`` returns None at once and ``open()`` raises;
    - ``mute``: opens fine but every ``read()`` returns None at once (a busy or broken stream).
    """

    def __init__(self, name: str = "fake", fps: float = 100.0, read_timeout: float = 0.2):
        self.name, self.fps, self.read_timeout = name, fps, read_timeout
        self.paused = threading.Event()
        self.gone = threading.Event()
        self.mute = threading.Event()
        self.fail_reads = 0
        self.reads = 0  # frames delivered
        self.opens = 0  # open attempts, failed ones included
        self.is_open = False
        self._next = time.monotonic()

    def open(self) -> None:
        self.opens += 1
        if self.gone.is_set():
            raise MomlocError(f"camera {self.name}: no such device")
        self.is_open = True
        self._next = time.monotonic()

    def read(self) -> np.ndarray | None:
        assert self.is_open, "read() on a closed source"
        if self.gone.is_set() or self.mute.is_set():
            return None
        if self.fail_reads > 0:
            self.fail_reads -= 1
            raise RuntimeError("boom")
        if self.paused.is_set():
            time.sleep(self.read_timeout)
            if self.paused.is_set():
                return None
        self._next += 1.0 / self.fps
        delay = self._next - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        else:
            self._next = time.monotonic()
        self.reads += 1
        return np.full((4, 4, 3), self.reads % 256, np.uint8)

    def close(self) -> None:
        self.is_open = False


class ManualClock:
    """A :class:`capture.worker.Clock` whose time moves only when the test says.

    ``wait`` blocks its thread until the test ends that wait with :meth:`step` (or the worker
    stops); :meth:`step` waits for the next wait of a thread whose name starts with ``prefix``,
    moves time to its end and releases it. A test thus walks the worker's back-off one wait
    at a time and sees exactly the waits the policy asks for, on a fast or a loaded machine.
    Other threads' waits (the watchdog's) end whenever time passes their end.
    """

    def __init__(self, start: float = 1_000_000.0) -> None:
        self.now = start
        self.waits: list[tuple[str, float]] = []  # (thread name, seconds), in order
        self._cond = threading.Condition()
        self._pending: dict[str, float] = {}  # sleeping thread -> when its wait ends

    def time(self) -> float:
        return self.now

    def wait(self, stop: threading.Event, seconds: float) -> bool:
        name = threading.current_thread().name
        with self._cond:
            end = self.now + seconds
            self.waits.append((name, seconds))
            self._pending[name] = end
            self._cond.notify_all()
            while self.now < end and not stop.is_set():
                self._cond.wait(0.05)  # stop is an Event, not this condition: poll it
            self._pending.pop(name, None)
            return stop.is_set()

    def step(self, prefix: str = "capture-", timeout: float = 10.0) -> float:
        """End the next wait of a ``prefix`` thread; returns its length."""
        with self._cond:
            found = self._cond.wait_for(
                lambda: any(n.startswith(prefix) for n in self._pending), timeout
            )
            assert found, f"no {prefix}* thread waited within {timeout} s"
            name = next(n for n in self._pending if n.startswith(prefix))
            end = self._pending.pop(name)  # popped: the next step waits for a new wait
            seconds = next(s for n, s in reversed(self.waits) if n == name)
            self.now = max(self.now, end)
            self._cond.notify_all()
            return seconds


def wait_until(predicate, timeout: float = 10.0, step: float = 0.005) -> bool:
    """Poll ``predicate`` until true or ``timeout`` (a liveness bound, not a timing test)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return bool(predicate())
