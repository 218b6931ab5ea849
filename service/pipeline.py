"""The live pipeline: frame set -> batched detection -> association -> MoM -> tracking -> hub.

Design
------
One dedicated thread runs the whole chain, so the asyncio loop serving clients is never blocked
and the chain needs no locks between stages. Each iteration takes the *newest* frame set from the
rig; frames that arrived while the previous set was being processed are skipped and counted as
dropped (camera workers keep one frame each), so a slow machine loses frame rate, never latency
or memory.

The MoM runtime is held by reference and swapped whole by :meth:`Pipeline.reload_model`; the next
iteration picks up the new one. A model whose camera count or image sizes disagree with the
cameras is refused with a :class:`MomlocError` and the running model stays.

Detection is a pluggable stage: ``detect(frame_set) -> [boxes [M_k, 4] per camera]``. The real
detector stage wraps ``models.detector``; the demo can feed the simulator's boxes through the very
same entry (see ``service.demo``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from models.errors import MomlocError
from service.camera_shift import CameraShiftMonitor, ShiftWorker
from service.hub import Hub, Snapshot
from service.measurements import coverage_function, measurement_covariances
from service.setup.camera_monitor import CameraMotionMonitor, CameraMoved, combine

log = logging.getLogger("momloc.pipeline")

DetectStage = Callable[[Any], list[np.ndarray]]


class Rig(Protocol):
    """What the pipeline needs from ``capture.CameraRig`` (or the synthetic rig)."""

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def frame_set(self, after: Any = None, timeout: float = 0.0) -> Any: ...
    def states(self) -> list[Any]: ...


class DetectorStage:
    """Real detector: one batched call for all cameras, low-score boxes removed.

    With ``schedule`` (a ``service.detection_schedule.DetectionScheduler``) the scheduler runs
    the detector beside the pipeline and carries boxes between detections instead.
    """

    def __init__(self, detector: Any, score_threshold: float, schedule: Any = None) -> None:
        self.detector = detector
        self.score_threshold = score_threshold
        self.schedule = schedule

    def stats(self) -> dict[str, Any] | None:
        return None if self.schedule is None else self.schedule.stats()

    def close(self) -> None:
        if self.schedule is not None:
            self.schedule.close()

    def __call__(self, frame_set: Any) -> list[np.ndarray]:
        if self.schedule is not None:
            return self.schedule(frame_set)
        frames = list(frame_set.frames)
        present = [k for k, f in enumerate(frames) if f is not None]
        out = [np.zeros((0, 4), np.float32) for _ in frames]
        if not present:
            return out
        results = self.detector.detect([frames[k].image for k in present])
        for k, det in zip(present, results, strict=True):
            keep = np.asarray(det.scores) >= self.score_threshold
            out[k] = np.asarray(det.boxes, np.float32)[keep].reshape(-1, 4)
        return out


@dataclass
class CameraView:
    """What the snapshot endpoint draws for one camera."""

    image: np.ndarray | None
    boxes: list[tuple[np.ndarray, int | None]] = field(default_factory=list)


def _image_size(frame: Any) -> tuple[int, int] | None:
    if frame is None or frame.image is None:
        return None
    h, w = frame.image.shape[:2]
    return int(w), int(h)


class Pipeline:
    """Runs the chain in its own thread and publishes one snapshot per processed frame set."""

    def __init__(
        self,
        rig: Rig,
        detect: DetectStage,
        hub: Hub,
        *,
        num_cameras: int,
        runtime: Any = None,
        model_dir: Path | None = None,
        tracker: Any = None,
        associate: Callable[..., list[Any]] | None = None,
        max_error_px: float = 100.0,  # service.association.DEFAULT_MAX_ERROR_PX
        load_runtime: Callable[[Path], Any] | None = None,
        shift_threaded: bool = True,
    ) -> None:
        if tracker is None:
            from service.tracking import RECOMMENDED, Tracker

            tracker = Tracker(fps_hint=30.0, **RECOMMENDED)
        if associate is None:
            from service.association import associate
        self.rig, self.detect, self.hub = rig, detect, hub
        self.num_cameras = num_cameras
        self.tracker, self.associate, self.max_error_px = tracker, associate, max_error_px
        self._load_runtime = load_runtime or _load_mom_runtime
        self.runtime, self.model_dir = runtime, model_dir
        self.image_sizes: list[tuple[int, int] | None] = [None] * num_cameras
        self.error: str | None = None
        self._seq = 0
        self._last_frame_seqs: tuple[int, ...] | None = None
        self._views = [CameraView(None) for _ in range(num_cameras)]
        self._view_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._done: deque[float] = deque(maxlen=120)  # publish times, for fps
        self._latency: deque[float] = deque(maxlen=600)  # capture -> publish, seconds
        self._stage_ms: dict[str, float] = {}
        self.frames_processed = 0
        self.frames_dropped = 0
        self.failures = 0
        self.last_failure: str | None = None
        self.alignment = CameraMotionMonitor(num_cameras)
        # image-based camera-moved check, ~1/s on its own thread (service.camera_shift)
        self.camera_shift = CameraShiftMonitor(num_cameras)
        self._shift_worker = ShiftWorker(self.camera_shift, threaded=shift_threaded)
        self._detection_listeners: list[Callable[[float, list[np.ndarray]], None]] = []

    def add_detection_listener(self, listener: Callable[[float, list[np.ndarray]], None]) -> None:
        """Call ``listener(t_capture, boxes per camera)`` for every frame set (must not block)."""
        self._detection_listeners = [*self._detection_listeners, listener]

    def remove_detection_listener(self, listener: Callable[..., None]) -> None:
        self._detection_listeners = [f for f in self._detection_listeners if f != listener]

    # -- lifecycle -------------------------------------------------------------------------------

    def start(self) -> None:
        self.rig.start()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="momloc-pipeline", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self._shift_worker.stop()
        close = getattr(self.detect, "close", None)
        if close is not None:
            close()  # the detection scheduler's worker thread, if any
        self.rig.stop()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def _run(self) -> None:
        previous = None
        while not self._stop.is_set():
            try:
                previous = self._step(previous)
            except Exception as exc:  # keep serving; the error shows in /v1/health
                self.error = self.last_failure = f"pipeline: {type(exc).__name__}: {exc}"
                self.failures += 1
                log.exception("pipeline iteration failed")
                self._stop.wait(0.1)

    def _step(self, previous: Any) -> Any:
        """Process the newest frame set if it is new; returns the set to wait after."""
        # waits (briefly) for frames newer than the last set instead of spinning
        frame_set = self.rig.frame_set(after=previous, timeout=0.1)
        seqs = self._frame_seqs(frame_set)
        if seqs is None or seqs == self._last_frame_seqs:
            self._stop.wait(0.002)
            return previous
        if self._last_frame_seqs is not None:
            self.frames_dropped += sum(
                max(0, new - old - 1)
                for new, old in zip(seqs, self._last_frame_seqs, strict=True)
                if new >= 0 and old >= 0
            )
        self._last_frame_seqs = seqs
        self.process(frame_set)
        return frame_set

    @staticmethod
    def _frame_seqs(frame_set: Any) -> tuple[int, ...] | None:
        if frame_set is None:
            return None
        seqs = tuple(-1 if f is None else int(f.seq) for f in frame_set.frames)
        return None if all(s < 0 for s in seqs) else seqs

    # -- one frame set ---------------------------------------------------------------------------

    def process(self, frame_set: Any) -> Snapshot:
        """Run the chain on one frame set and publish the result (callable without the thread)."""
        frames = list(frame_set.frames)
        stamps = [f.timestamp for f in frames if f is not None]
        t_capture = float(min(stamps)) if stamps else time.time()
        t0 = time.perf_counter()
        detections = self.detect(frame_set)
        for listener in self._detection_listeners:
            listener(t_capture, detections)
        t1 = time.perf_counter()
        for k, f in enumerate(frames):
            size = _image_size(f)
            if size is not None:
                self.image_sizes[k] = size
        self._shift_worker.submit(t_capture, [None if f is None else f.image for f in frames])
        runtime = self.runtime
        associations: list[Any] = []
        self.error = None  # this iteration's state only; failures are counted separately
        if runtime is not None:
            problem = self._sizes_match(runtime)
            if problem is None:
                associations = self.associate(detections, runtime, max_error_px=self.max_error_px)
                self._watch_alignment(runtime, associations, t_capture)
            else:
                self.error = f"model: {problem}"
        t2 = time.perf_counter()
        self._seq += 1
        meta = [
            {"cameras": [int(c) for c in a.cameras], "frame": self._seq, "association": i}
            for i, a in enumerate(associations)
        ]
        positions = np.array([np.asarray(a.world, float)[:2] for a in associations]).reshape(-1, 2)
        # the tracker weighs each position by its covariance (a lone view is trusted across its
        # line of sight, hardly along it) and drops single-view ghosts where another camera that
        # delivered a frame should see the person (service.measurements)
        tracks = self.tracker.update(
            t_capture,
            positions,
            meta,
            covariances=measurement_covariances(associations, runtime),
            coverage=coverage_function(runtime, [f is not None for f in frames]),
        )
        t3 = time.perf_counter()
        people = [_person(tr) for tr in tracks]
        snapshot = Snapshot.build(self._seq, t_capture, people)
        self.hub.publish(snapshot)
        now = time.time()
        self._record(frames, detections, associations, tracks, t_capture, now)
        self._stage_ms = {
            "detect": (t1 - t0) * 1e3,
            "associate": (t2 - t1) * 1e3,
            "track": (t3 - t2) * 1e3,
        }
        return snapshot

    def _watch_alignment(self, runtime: Any, associations: Sequence[Any], t: float) -> None:
        """Feed the camera-moved monitor with the decoder's reprojection error of people seen by
        two or more cameras (a lone view always agrees with its own prediction)."""
        multi = [a for a in associations if len(a.cameras) >= 2]
        if not multi:
            return
        boxes = np.stack([np.asarray(a.boxes, np.float32) for a in multi])
        world = np.stack([np.asarray(a.world, np.float64)[:2] for a in multi])
        self.alignment.update(t, runtime.reprojection_error(boxes, world))

    def _record(
        self,
        frames: Sequence[Any],
        detections: Sequence[np.ndarray],
        associations: Sequence[Any],
        tracks: Sequence[Any],
        t_capture: float,
        now: float,
    ) -> None:
        ids: dict[tuple[int, int], int] = {}
        for tr in tracks:
            meta = getattr(tr, "meta", None) or {}
            if meta.get("frame") != self._seq:
                continue
            a = associations[meta["association"]]
            for k, j in enumerate(a.detection_index):
                if j is not None:
                    ids[(k, int(j))] = int(tr.id)
        with self._view_lock:
            for k, f in enumerate(frames):
                if f is not None and f.image is not None:  # frames without pixels keep the last
                    boxes = [(box, ids.get((k, j))) for j, box in enumerate(detections[k])]
                    self._views[k] = CameraView(f.image, boxes)
        self.frames_processed += 1
        self._done.append(now)
        self._latency.append(now - t_capture)

    def _sizes_match(self, runtime: Any) -> str | None:
        """Why ``runtime`` cannot serve these cameras, or None when it can."""
        if int(runtime.num_cameras) != self.num_cameras:
            return f"model expects {runtime.num_cameras} cameras, {self.num_cameras} are configured"
        for k, size in enumerate(self.image_sizes):
            expected = tuple(int(v) for v in np.asarray(runtime.image_sizes)[k])
            if size is not None and size != expected:
                return (
                    f"model expects {expected[0]}x{expected[1]} images from camera {k}, "
                    f"the camera delivers {size[0]}x{size[1]}"
                )
        return None

    # -- model hot swap --------------------------------------------------------------------------

    def reload_model(self, model_dir: str | Path | None = None) -> dict[str, Any]:
        """Load ``model_dir`` (default: the current one) and swap it in if it fits the cameras."""
        path = Path(model_dir) if model_dir is not None else self.model_dir
        if path is None:
            raise MomlocError("no model directory configured")
        runtime = self._load_runtime(path)
        problem = self._sizes_match(runtime)
        if problem is not None:
            raise MomlocError(f"{path}: {problem}; keeping the current model")
        self.runtime, self.model_dir = runtime, path
        self.reset_alignment()  # a new model (new floor marks): new baseline and references
        if self.error and self.error.startswith("model"):
            self.error = None
        log.info("model loaded from %s", path)
        return self.model_info()

    def reset_alignment(self) -> None:
        """Accept the cameras where they are now: new error baseline and image references."""
        self.alignment = CameraMotionMonitor(self.num_cameras)
        self.camera_shift.reset()

    def alignment_status(self, names: Sequence[str] | None = None) -> list[CameraMoved]:
        """Per camera: image shift and reprojection error combined into one moved verdict."""
        return combine(self.alignment.status(), self.camera_shift.status(), names)

    def model_info(self) -> dict[str, Any]:
        runtime = self.runtime
        if runtime is None:
            return {"loaded": False, "path": str(self.model_dir) if self.model_dir else None}
        problem = self._sizes_match(runtime)
        return {
            "loaded": True,
            "path": str(self.model_dir) if self.model_dir else None,
            "num_cameras": int(runtime.num_cameras),
            "image_sizes": np.asarray(runtime.image_sizes).astype(int).tolist(),
            "observation": getattr(runtime, "observation", "bbox"),
            "compatible": problem is None,
            "problem": problem,
        }

    # -- introspection ---------------------------------------------------------------------------

    def view(self, camera: int) -> CameraView:
        with self._view_lock:
            return self._views[camera]

    def stats(self) -> dict[str, Any]:
        """Frame rate over the last ~4 s, latency percentiles, stage timings, counters."""
        now = time.time()
        recent = [t for t in self._done if now - t <= 4.0]
        fps = 0.0
        if len(recent) >= 2 and recent[-1] > recent[0]:
            fps = (len(recent) - 1) / (recent[-1] - recent[0])
        lat = np.array(self._latency, float) * 1e3
        return {
            "running": self.running,
            "fps": round(fps, 2),
            "latency_ms": {
                "p50": round(float(np.percentile(lat, 50)), 2) if lat.size else None,
                "p95": round(float(np.percentile(lat, 95)), 2) if lat.size else None,
            },
            "stage_ms": {k: round(v, 2) for k, v in self._stage_ms.items()},
            "detection": getattr(self.detect, "stats", lambda: None)(),
            "seq": self._seq,
            "frames_processed": self.frames_processed,
            "frames_dropped": self.frames_dropped,
            "error": self.error,
            "failures": self.failures,
            "last_failure": self.last_failure,
        }


def _person(track: Any) -> dict[str, Any]:
    return {
        "id": int(track.id),
        "x": round(float(track.x), 4),
        "y": round(float(track.y), 4),
        "vx": round(float(track.vx), 4),
        "vy": round(float(track.vy), 4),
        "confidence": round(float(np.clip(track.confidence, 0.0, 1.0)), 3),
        "cameras": [int(k) for k in track.cameras],
    }


def _load_mom_runtime(path: Path) -> Any:
    from models.mom_runtime import MomRuntime

    return MomRuntime.load(path)
