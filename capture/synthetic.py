"""Synthetic cameras: a simulated scene rendered per camera in lock-step.

Design: one clock drives every synthetic camera, so camera k and camera j always show the same
scene frame (a real rig has skew; the simulator's frames are simultaneous by construction). The
scene frame index is the frame's ``seq``; ``timestamp`` is the wall-clock time the frame was
produced. Both let tests and the demo find the scene frame behind whatever the pipeline reports
(``index_at(t)``), whose ground truth the simulator gives (``scene.observe(index)``).

Two ways in:

- :class:`SyntheticRig` has the ``CameraRig`` interface (``start``/``stop``/``frame_set``/
  ``states``) and renders all cameras of one tick in one thread: what ``momloc demo`` uses.
- :class:`SyntheticSource` is a ``FrameSource`` for one camera (for ``CameraWorker``), sharing a
  :class:`SceneClock` with its siblings.

Capture gives frames only: the scene is anything with the :class:`RenderedScene` shape (the
simulator's ``models.simulate.Scene``, built by ``models.simulate.make_scene``), so this module
imports nothing of ``models``. Ground truth and the simulator's own boxes (the demo's
``simulated`` detections) are the simulator's and the service's business
(``service.detection.simulated``).
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Sequence
from typing import Protocol, TypeVar

import numpy as np

from capture.rig import FrameSet
from capture.worker import CameraState, Frame
from common.worker_thread import WorkerThread


class RenderedScene(Protocol):
    """What synthetic cameras need of a scene: its frame rate, camera count and images."""

    @property
    def fps(self) -> float: ...

    @property
    def num_cameras(self) -> int: ...

    def render(self, frame_index: int, camera_index: int) -> np.ndarray:
        """uint8 BGR [H, W, 3]: what camera ``camera_index`` sees at scene frame ``frame_index``."""
        ...


class SceneClock:
    """Maps wall-clock time to scene frame indices for every camera of one scene."""

    def __init__(self, scene: RenderedScene, fps: float | None = None, *, cache: int = 64) -> None:
        self.scene = scene
        self.fps = float(fps or scene.fps)
        self.t0 = time.time()
        self._lock = threading.Lock()
        self._images: OrderedDict[tuple[int, int], np.ndarray] = OrderedDict()
        self._stamps: OrderedDict[int, float] = OrderedDict()
        self._cache = cache

    def index_now(self) -> int:
        return int((time.time() - self.t0) * self.fps)

    def tick_time(self, index: int) -> float:
        return self.t0 + index / self.fps

    def wait_for(self, index: int, stop: threading.Event | None = None) -> None:
        delay = self.tick_time(index) - time.time()
        if delay > 0:
            if stop is not None:
                stop.wait(delay)
            else:
                time.sleep(delay)

    def stamp(self, index: int, timestamp: float) -> None:
        with self._lock:
            self._stamps.setdefault(index, timestamp)
            _trim(self._stamps, self._cache * 8)

    def index_at(self, timestamp: float) -> int:
        """The scene frame of the frames stamped ``timestamp`` (a snapshot's ``t``)."""
        with self._lock:
            matches = [i for i, s in self._stamps.items() if abs(s - timestamp) < 1e-6]
        return matches[0] if matches else round((timestamp - self.t0) * self.fps)

    def render(self, index: int, camera: int) -> np.ndarray:
        key = (index, camera)
        with self._lock:
            if key in self._images:
                return self._images[key]
        image = self.scene.render(index, camera)
        with self._lock:
            self._images[key] = image
            _trim(self._images, self._cache)
        return image


_Key = TypeVar("_Key")
_Value = TypeVar("_Value")


def _trim(cache: OrderedDict[_Key, _Value], size: int) -> None:
    while len(cache) > size:
        cache.popitem(last=False)


class SyntheticRig(SceneClock):
    """All cameras of a scene, one render thread, newest frame set only (``CameraRig`` shape).

    ``render_every=n`` draws every n-th scene frame only (others carry ``image=None``): drawing
    costs ~15 ms per camera, so with simulated detections the previews are drawn at a few Hz.
    """

    def __init__(
        self,
        scene: RenderedScene,
        cameras: Sequence[int] | None = None,
        *,
        fps: float | None = None,
        render_every: int = 1,
    ) -> None:
        super().__init__(scene, fps)
        self.cameras = list(range(scene.num_cameras)) if cameras is None else list(cameras)
        self.render_every = render_every
        self._latest: FrameSet | None = None
        self._new_frames = threading.Condition()
        self._worker = WorkerThread(self._run, "synthetic-rig")
        self._stop = self._worker.stopping
        self._produced: list[float] = []

    def start(self) -> None:
        self.t0 = time.time()
        self._worker.start()

    def stop(self) -> None:
        self._worker.stop()

    def _run(self) -> None:
        index = 0
        while not self._stop.is_set():
            index = max(index + 1, self.index_now())
            self.wait_for(index, self._stop)
            if self._stop.is_set():
                break
            frame_set = self.produce(index)
            with self._new_frames:
                self._latest = frame_set
                self._new_frames.notify_all()

    def produce(self, index: int) -> FrameSet:
        """Render scene frame ``index`` for every camera (also usable without the thread).

        Stamped once drawn, like a camera worker stamping a frame when it arrives: latency
        measured from ``timestamp`` is the daemon's, not the simulator's drawing time.
        """
        drawn = self.render_every > 0 and index % self.render_every == 0
        images = [self.render(index, camera) if drawn else None for camera in self.cameras]
        timestamp = time.time()
        self.stamp(index, timestamp)
        frames: list[Frame | None] = [
            Frame(camera=k, image=image, timestamp=timestamp, seq=index)
            for k, image in enumerate(images)
        ]
        self._produced = [*self._produced[-59:], timestamp]
        return FrameSet(frames=frames, skew=0.0)

    def frame_set(self, after: FrameSet | None = None, timeout: float = 0.0) -> FrameSet | None:
        """Newest frame set; with ``after``, wait up to ``timeout`` s for a newer one."""
        with self._new_frames:
            if after is not None and timeout > 0:
                self._new_frames.wait_for(lambda: self._latest is not after, timeout)
            return self._latest

    def states(self) -> list[CameraState]:
        now = time.time()
        stamps = self._produced
        fps = (len(stamps) - 1) / (stamps[-1] - stamps[0]) if len(stamps) > 1 else 0.0
        age = now - stamps[-1] if stamps else None
        alive = self._worker.alive
        return [
            CameraState(
                connected=alive and age is not None and age < 2.0,
                fps=fps,
                last_frame_age=age,
                reconnects=0,
                error=None,
                name=f"synthetic-{camera}",
            )
            for camera in self.cameras
        ]


class SyntheticSource:
    """``FrameSource`` for one simulated camera; siblings share a :class:`SceneClock`."""

    def __init__(self, clock: SceneClock, camera: int) -> None:
        self.clock, self.camera = clock, camera
        self.name = f"synthetic-{camera}"
        self._next = 0
        self._open = False
        self.last_index: int | None = None  # scene frame of the newest image read

    def open(self) -> None:
        self._open = True
        self._next = self.clock.index_now() + 1

    def read(self) -> np.ndarray | None:
        if not self._open:
            return None
        index = max(self._next, self.clock.index_now())
        self.clock.wait_for(index)
        self._next = index + 1
        self.clock.stamp(index, time.time())
        image = self.clock.render(index, self.camera)
        self.last_index = index
        return image

    def close(self) -> None:
        self._open = False
