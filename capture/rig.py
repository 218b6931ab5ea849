"""All cameras together: start/stop the workers and take frame sets of their newest frames.

A *frame set* is what one pipeline step consumes: the newest frame of every camera, with how far
apart in time they were taken (``skew``). Real USB webcams are not synchronised, so a walking
person moves between the cameras' exposures; the pipeline can weigh or drop views using
``stale`` (frames more than ``max_skew`` older than the newest) and gets ``None`` for a camera
that has no usable frame (disconnected, or its newest frame is older than ``max_age``).

:meth:`CameraRig.frame_set` can wait for *new* frames (``after=`` the previous set), so a
pipeline faster than the cameras does not process the same images twice, and a pipeline slower
than the cameras simply gets the newest ones (older frames were dropped by the workers).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

from capture.worker import CameraState, Frame


@dataclass(frozen=True)
class FrameSet:
    """Newest frame per camera (index = camera; None where unusable) and their time skew (s)."""

    frames: list[Frame | None]
    skew: float
    stale: list[bool] = field(default_factory=list)

    @property
    def timestamp(self) -> float | None:
        """Capture time of the *oldest* frame used: latency measured from it is an upper bound."""
        times = [f.timestamp for f in self.frames if f is not None]
        return min(times) if times else None

    @property
    def available(self) -> list[int]:
        return [k for k, f in enumerate(self.frames) if f is not None]


class Worker(Protocol):
    """What the rig needs of one camera's :class:`~capture.worker.CameraWorker`."""

    camera: int

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def latest(self) -> Frame | None: ...
    def wait_for_frame(self, after_seq: int = -1, timeout: float | None = None) -> Frame | None: ...
    def state(self) -> CameraState: ...


class CameraRig:
    """A set of :class:`~capture.worker.CameraWorker` (camera index = position in ``workers``)."""

    def __init__(
        self, workers: Sequence[Worker], max_skew: float = 0.05, max_age: float = 1.0
    ) -> None:
        self.workers = list(workers)
        for index, worker in enumerate(self.workers):
            worker.camera = index  # frames carry their position in the rig
        self.max_skew, self.max_age = float(max_skew), float(max_age)

    def start(self) -> None:
        for worker in self.workers:
            worker.start()

    def stop(self) -> None:
        for worker in self.workers:
            worker.stop()

    def __enter__(self) -> CameraRig:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def states(self) -> list[CameraState]:
        return [worker.state() for worker in self.workers]

    def frame_set(self, after: FrameSet | None = None, timeout: float = 0.0) -> FrameSet | None:
        """The newest frame of every camera, or None when no camera has produced any yet.

        With ``after`` and ``timeout`` > 0, first wait (up to ``timeout`` s in total) until every
        connected camera has a frame newer than in ``after``; cameras that are down are not
        waited for.
        """
        if after is not None and timeout > 0:
            deadline = time.monotonic() + timeout
            for k, worker in enumerate(self.workers):
                previous = after.frames[k] if k < len(after.frames) else None
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                if worker.state().connected:
                    worker.wait_for_frame(previous.seq if previous else -1, remaining)
        return self._assemble(time.time())

    def _assemble(self, now: float) -> FrameSet | None:
        frames: list[Frame | None] = []
        for worker in self.workers:
            frame = worker.latest()
            frames.append(
                frame if frame is not None and now - frame.timestamp <= self.max_age else None
            )
        times = [f.timestamp for f in frames if f is not None]
        if not times:
            return None
        newest = max(times)
        stale = [f is not None and newest - f.timestamp > self.max_skew for f in frames]
        return FrameSet(frames=frames, skew=newest - min(times), stale=stale)
