"""What hangs off the pipeline: listeners of each frame set's
:class:`~service.stages.FrameResult`.

The pipeline (``service.pipeline.live``) runs detect -> associate -> localize -> track -> publish
and then hands the whole result to its listeners, in its own thread, after the snapshot is out. Each
listener here does one job and must stay cheap (a copy of a reference, a deque append); anything
slow runs on its own thread (the image camera-moved check does, see
``service.camera_health.image_shift``; so does the self-label collector,
``service.learning.listener``). A listener with a ``close()`` is closed when the pipeline stops.

- :class:`CameraWatch`: the two camera-moved checks (decoder reprojection error of people seen
  by two or more cameras, and the image shift of the static background), combined per camera.
- :class:`Previews`: the newest image of each camera with its boxes and track ids, for
  ``/v1/cameras/{k}/snapshot.jpg`` and ``/v1/cameras/{k}/boxes``; without images (settings
  ``privacy: positions_only``) the boxes and the frame size only.
- :class:`Throughput`: frame rate, capture -> publish latency and stage timings for health.
- :class:`DetectionTap`: adapts a ``(t_capture, boxes per camera)`` callback (the set-up recorder)
  to a listener.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service.camera_health.image_shift import CameraShiftMonitor, ShiftWorker
from service.camera_health.reprojection import CameraMotionMonitor, CameraMoved, combine
from service.stages import FrameResult, LocalizationModel


class CameraWatch:
    """Camera-moved monitoring fed by every frame result (see
    ``service.camera_health.reprojection``)."""

    def __init__(self, num_cameras: int, *, shift_threaded: bool = True) -> None:
        self.num_cameras = num_cameras
        self.alignment = CameraMotionMonitor(num_cameras)
        self.camera_shift = CameraShiftMonitor(num_cameras)  # ~1/s on its own thread
        self._shift_worker = ShiftWorker(self.camera_shift, threaded=shift_threaded)
        self._runtime: LocalizationModel | None = None

    def __call__(self, result: FrameResult) -> None:
        frames = result.frame_set.frames
        self._shift_worker.submit(
            result.t_capture, [None if f is None else f.image for f in frames]
        )
        runtime = result.runtime
        if runtime is None:
            return
        if self._runtime is not None and runtime is not self._runtime:
            self.reset()  # a new model (new floor marks): new baseline and references
        self._runtime = runtime
        # a lone view always agrees with its own prediction: only people seen twice or more
        multi = [a for a in result.associations if len(a.cameras) >= 2]
        if not multi:
            return
        boxes = np.stack([np.asarray(a.boxes, np.float32) for a in multi])
        world = np.stack([np.asarray(a.world, np.float64)[:2] for a in multi])
        if runtime.observation == "keypoints":
            keypoints = np.stack([np.asarray(a.keypoints, np.float32) for a in multi])
            errors = runtime.reprojection_error(boxes, world, keypoints)
        else:
            errors = runtime.reprojection_error(boxes, world)
        self.alignment.update(result.t_capture, errors)

    def reset(self) -> None:
        """Accept the cameras where they are now: new error baseline and image references."""
        self.alignment = CameraMotionMonitor(self.num_cameras)
        self.camera_shift.reset()

    def status(self, names: Sequence[str] | None = None) -> list[CameraMoved]:
        """Per camera: image shift and reprojection error combined into one moved verdict."""
        return combine(self.alignment.status(), self.camera_shift.status(), names)

    def close(self) -> None:
        self._shift_worker.stop()


@dataclass
class CameraView:
    """What the preview endpoints show for one camera: the frame (None without images), the
    boxes with the ids of the tracks they fed, and the frame's width and height."""

    image: np.ndarray | None
    boxes: list[tuple[np.ndarray, int | None]] = field(default_factory=list)
    size: tuple[int, int] | None = None


class Previews:
    """The newest drawn frame per camera with its boxes and the ids of the tracks they fed.

    ``images=False`` (privacy mode) keeps no reference to any frame: a view holds the boxes and
    the frame size only, so no code path that reads views can serve or write pixels.
    """

    def __init__(self, num_cameras: int, *, images: bool = True) -> None:
        self.images = images
        self._views = [CameraView(None) for _ in range(num_cameras)]
        self._lock = threading.Lock()

    def __call__(self, result: FrameResult) -> None:
        ids = result.track_ids()
        with self._lock:
            for k, frame in enumerate(result.frame_set.frames):
                # no pixels, or left out of fusion by the skew rule: keep the last view
                if frame is not None and frame.image is not None and result.fused[k]:
                    boxes = result.detections[k].boxes
                    height, width = frame.image.shape[:2]
                    self._views[k] = CameraView(
                        frame.image if self.images else None,
                        [(box, ids.get((k, j))) for j, box in enumerate(boxes)],
                        (int(width), int(height)),
                    )

    def view(self, camera: int) -> CameraView:
        with self._lock:
            return self._views[camera]


class Throughput:
    """Frame rate over the last ~4 s, capture -> publish latency percentiles, stage timings.

    Written by the pipeline thread, read by /v1/health and /metrics on server threads: both
    hold the lock (iterating a deque while another thread appends raised "deque mutated during
    iteration", a 500 from /v1/health under load)."""

    def __init__(self, clock: Callable[[], float] = time.time) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._done: deque[float] = deque(maxlen=120)  # publish times, for fps
        self._latency: deque[float] = deque(maxlen=600)  # capture -> publish, seconds
        self._stage_ms: dict[str, float] = {}

    def __call__(self, result: FrameResult) -> None:
        now = self._clock()
        with self._lock:
            self._done.append(now)
            self._latency.append(now - result.t_capture)
            self._stage_ms = dict(result.timings_ms)

    def latencies_ms(self) -> np.ndarray:
        """The recent capture -> publish latencies, in milliseconds."""
        with self._lock:
            return np.array(self._latency, float) * 1e3

    def clear_latencies(self) -> None:
        with self._lock:
            self._latency.clear()

    def stats(self) -> dict[str, Any]:
        now = self._clock()
        with self._lock:
            recent = [t for t in self._done if now - t <= 4.0]
            stage_ms = dict(self._stage_ms)
        fps = 0.0
        if len(recent) >= 2 and recent[-1] > recent[0]:
            fps = (len(recent) - 1) / (recent[-1] - recent[0])
        lat = self.latencies_ms()
        return {
            "fps": round(fps, 2),
            "latency_ms": {
                "p50": round(float(np.percentile(lat, 50)), 2) if lat.size else None,
                "p95": round(float(np.percentile(lat, 95)), 2) if lat.size else None,
            },
            "stage_ms": {k: round(v, 2) for k, v in stage_ms.items()},
        }


class DetectionTap:
    """Calls ``callback(t_capture, boxes per camera)`` for every frame set (must not block)."""

    def __init__(self, callback: Callable[[float, list[np.ndarray]], None]) -> None:
        self.callback = callback

    def __call__(self, result: FrameResult) -> None:
        self.callback(result.t_capture, [d.boxes for d in result.detections])
