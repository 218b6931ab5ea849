"""The live pipeline: frame set -> batched detection -> association -> MoM -> tracking -> hub.

Design
------
One dedicated thread runs the whole chain, so the asyncio loop serving clients is never blocked
and the chain needs no locks between stages. Each iteration takes the *newest* frame set from the
rig; frames that arrived while the previous set was being processed are skipped and counted as
dropped (camera workers keep one frame each), so a slow machine loses frame rate, never latency
or memory.

The pipeline runs the chain only. The values passed between stages are the typed contracts of
``service.stages``; after publishing, the whole
:class:`~service.stages.FrameResult` goes to the listeners (``service.pipeline.listeners``:
camera-moved checks, previews, throughput, the set-up recorder), which cannot change what was
published. :meth:`Pipeline.process` is the one entry for a frame set, used by the thread live and
callable directly (offline replays, tests).

Skew rule: USB webcams are not synchronised, so the newest frames of two cameras can be tens of
milliseconds apart, and a walking person (1.4 m/s) moves 7 cm in 50 ms. The rig marks a frame
``stale`` when it is more than ``max_skew`` older than the newest frame of the set
(``capture.rig``, setting ``tracking.max_skew_s``, default 0.05 s). Stale frames are *left out*
of detection and fusion: the set is localized as one instant from the newest consistent subset,
and a person seen only by the late camera is localized from the others (the MoM model supports
missing views) or not at all this time. Rejected: skipping the whole set (a camera that runs
slower or lags would stall every update, where leaving it out costs only that view for one
step; the next set normally has it fresh again) and fusing anyway (association then compares a
person at two different places and may split them into two).

The MoM runtime is held by reference and swapped whole by :meth:`Pipeline.reload_model`; the next
iteration picks up the new one. A model that cannot serve these cameras (camera count, image
sizes, or keypoints from a detector that has none) or whose encoder does not run (the test
inference of ``MomRuntime.load``) is refused with a :class:`MomlocError` and the running model
stays. A frame set that fails anyway is logged once, then counted
(``service.pipeline.failure_log``).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np

from capture.rig import FrameSet
from capture.worker import CameraState, Frame
from common.errors import MomlocError
from common.worker_thread import WorkerThread
from service.camera_health.reprojection import CameraMoved
from service.pipeline.chain import Chain, OutsideArea, served_inside
from service.pipeline.failure_log import FailureLog
from service.pipeline.hub import Hub
from service.pipeline.listeners import CameraView, CameraWatch, DetectionTap, Previews, Throughput
from service.snapshot import Person, Snapshot
from service.stages import (
    AssociateStage,
    Closeable,
    DetectStage,
    FrameListener,
    FrameResult,
    LocalizationModel,
    Track,
    TrackStage,
)
from service.tracking.association import DEFAULT_MAX_ERROR_PX

log = logging.getLogger("momloc.pipeline")


class Rig(Protocol):
    """What the pipeline needs from ``capture.CameraRig`` (or the synthetic rig)."""

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def frame_set(self, after: FrameSet | None = None, timeout: float = 0.0) -> FrameSet | None: ...
    def states(self) -> list[CameraState]: ...


def _image_size(frame: Frame | None) -> tuple[int, int] | None:
    if frame is None or frame.image is None:
        return None
    h, w = frame.image.shape[:2]
    return int(w), int(h)


def fusable(frame_set: FrameSet) -> tuple[FrameSet, list[bool]]:
    """The skew rule (module docstring): the frame set without its stale frames, and per camera
    whether its frame takes part."""
    frames = list(frame_set.frames)
    stale = list(frame_set.stale or [False] * len(frames))
    fused = [f is not None and not s for f, s in zip(frames, stale, strict=True)]
    if all(f is None or keep for f, keep in zip(frames, fused, strict=True)):
        return frame_set, fused
    kept = [f if keep else None for f, keep in zip(frames, fused, strict=True)]
    times = [f.timestamp for f in kept if f is not None]
    skew = max(times) - min(times) if times else 0.0
    return FrameSet(frames=kept, skew=skew, stale=[False] * len(kept)), fused


class Pipeline:
    """Runs the chain in its own thread and publishes one snapshot per processed frame set."""

    def __init__(
        self,
        rig: Rig,
        detect: DetectStage,
        hub: Hub,
        *,
        num_cameras: int,
        runtime: LocalizationModel | None = None,
        model_dir: Path | None = None,
        tracker: TrackStage | None = None,
        associate: AssociateStage | None = None,
        max_error_px: float = DEFAULT_MAX_ERROR_PX,
        outside_area: OutsideArea = "drop",
        load_runtime: Callable[[Path], LocalizationModel] | None = None,
        shift_threaded: bool = True,
        preview_images: bool = True,
    ) -> None:
        if tracker is None:
            from service.tracking.tracker import RECOMMENDED, Tracker

            tracker = Tracker(fps_hint=30.0, **RECOMMENDED)
        self.rig, self.detect, self.hub = rig, detect, hub
        self.num_cameras = num_cameras
        # associate -> set-up area -> lone-view correction -> tracker: the one chain
        # (service.pipeline.chain)
        self.chain = Chain(
            tracker, associate=associate, max_error_px=max_error_px, outside_area=outside_area
        )
        self._load_runtime = load_runtime or _load_mom_runtime
        self.runtime, self.model_dir = runtime, model_dir
        self.image_sizes: list[tuple[int, int] | None] = [None] * num_cameras
        self.error: str | None = None
        self._seq = 0
        self._last_frame_seqs: tuple[int, ...] | None = None
        self._worker = WorkerThread(self._run, "momloc-pipeline")
        self._stop = self._worker.stopping
        self.frames_processed = 0
        self.frames_dropped = 0
        self.views_left_out = 0  # frames left out of fusion by the skew rule
        self.failures = 0
        self.last_failure: str | None = None
        self.failure_log = FailureLog(log, "frame sets")
        # the standard listeners (service.pipeline.listeners); more via add_listener
        self.camera_watch = CameraWatch(num_cameras, shift_threaded=shift_threaded)
        self.previews = Previews(num_cameras, images=preview_images)
        self.throughput = Throughput()
        self._listeners: list[FrameListener] = [self.camera_watch, self.previews, self.throughput]
        self._taps: dict[Callable[..., None], DetectionTap] = {}
        if runtime is not None:
            self.check_model(runtime, f"model_dir: {model_dir}")  # the one load-time check

    def add_listener(self, listener: FrameListener) -> None:
        """Call ``listener(result)`` after every published frame set (must not block)."""
        self._listeners = [*self._listeners, listener]

    def remove_listener(self, listener: FrameListener) -> None:
        self._listeners = [f for f in self._listeners if f is not listener]

    def add_detection_listener(self, listener: Callable[[float, list[np.ndarray]], None]) -> None:
        """Call ``listener(t_capture, boxes per camera)`` for every frame set (must not block)."""
        self._taps[listener] = tap = DetectionTap(listener)
        self.add_listener(tap)

    def remove_detection_listener(self, listener: Callable[..., None]) -> None:
        tap = self._taps.pop(listener, None)
        if tap is not None:
            self.remove_listener(tap)

    # -- lifecycle -------------------------------------------------------------------------------

    def start(self) -> None:
        self.rig.start()
        self._worker.start()

    def stop(self) -> None:
        self._worker.stop()
        for listener in self._listeners:  # those with a thread or pending writes
            if isinstance(listener, Closeable):
                listener.close()
        self.detect.close()  # the detection scheduler's worker thread, if any
        self.rig.stop()

    @property
    def running(self) -> bool:
        return self._worker.alive

    def _run(self) -> None:
        previous: FrameSet | None = None
        while not self._stop.is_set():
            try:
                processed = self._step(previous)
            except Exception as exc:  # keep serving; the error shows in /v1/health
                self.error = self.last_failure = f"pipeline: {type(exc).__name__}: {exc}"
                self.failures += 1
                self.failure_log.failed(exc)  # once with its traceback, then counted
                self._stop.wait(0.1)
                continue
            if processed is not previous:
                self.failure_log.succeeded()
            previous = processed

    def _step(self, previous: FrameSet | None) -> FrameSet | None:
        """Process the newest frame set if it is new; returns the set to wait after."""
        # waits (briefly) for frames newer than the last set instead of spinning
        frame_set = self.rig.frame_set(after=previous, timeout=0.1)
        seqs = self._frame_seqs(frame_set)
        if frame_set is None or seqs is None or seqs == self._last_frame_seqs:
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
    def _frame_seqs(frame_set: FrameSet | None) -> tuple[int, ...] | None:
        if frame_set is None:
            return None
        seqs = tuple(-1 if f is None else int(f.seq) for f in frame_set.frames)
        return None if all(s < 0 for s in seqs) else seqs

    # -- one frame set ---------------------------------------------------------------------------

    def process(self, frame_set: FrameSet) -> Snapshot:
        """Run the chain on one frame set, publish the snapshot, then tell the listeners."""
        frames = list(frame_set.frames)
        stamps = [f.timestamp for f in frames if f is not None]
        t_capture = float(min(stamps)) if stamps else time.time()
        for k, f in enumerate(frames):
            size = _image_size(f)
            if size is not None:
                self.image_sizes[k] = size
        t0 = time.perf_counter()
        used, fused = fusable(frame_set)
        self.views_left_out += sum(
            f is not None and not keep for f, keep in zip(frames, fused, strict=True)
        )
        used_stamps = [f.timestamp for f in used.frames if f is not None]
        t_used = float(min(used_stamps)) if used_stamps else t_capture  # the snapshot's ``t``
        detections = list(self.detect(used))
        t1 = time.perf_counter()
        runtime = self.runtime
        self.error = None  # this iteration's state only; failures are counted separately
        problem = None if runtime is None else self._incompatibility(runtime)
        if problem is not None:
            self.error = f"model: {problem}"
        self._seq += 1
        delivered = [f is not None for f in used.frames]
        associations, tracks = self.chain(
            t_used, detections, runtime if problem is None else None, delivered, self._seq
        )
        snapshot = Snapshot.build(self._seq, t_used, [served_person(tr) for tr in tracks])
        if runtime is not None:  # set-up mode (no model) publishes no positions at all
            self.hub.publish(snapshot)
        self.frames_processed += 1
        result = FrameResult(
            frame_set=frame_set,
            t_capture=t_used,
            fused=fused,
            detections=detections,
            associations=associations,
            tracks=tracks,
            snapshot=snapshot,
            runtime=runtime,
            timings_ms={"detect": (t1 - t0) * 1e3, **self.chain.timings_ms},
            outside=self.chain.outside,
        )
        for listener in self._listeners:
            listener(result)
        return snapshot

    def _incompatibility(self, runtime: LocalizationModel) -> str | None:
        """Why ``runtime`` cannot serve these cameras and this detector, or None when it can."""
        if int(runtime.num_cameras) != self.num_cameras:
            return f"model expects {runtime.num_cameras} cameras, {self.num_cameras} are configured"
        if runtime.observation == "keypoints" and not self.detect.keypoints:
            return (
                "model reads keypoints (trained with --observation keypoints) but the detector "
                "gives boxes only (set detector.keypoints: true, needs momloc[keypoints])"
            )
        for k, size in enumerate(self.image_sizes):
            expected = tuple(int(v) for v in np.asarray(runtime.image_sizes)[k])
            if size is not None and size != expected:
                return (
                    f"model expects {expected[0]}x{expected[1]} images from camera {k}, "
                    f"the camera delivers {size[0]}x{size[1]}"
                )
        return None

    def check_model(self, runtime: LocalizationModel, path: Path | str | None) -> None:
        """Raise :class:`MomlocError` (one line) when ``runtime`` cannot serve this pipeline."""
        problem = self._incompatibility(runtime)
        if problem is not None:
            raise MomlocError(f"{path}: {problem}")

    # -- model hot swap --------------------------------------------------------------------------

    def reload_model(self, model_dir: str | Path | None = None) -> dict[str, Any]:
        """Load ``model_dir`` (default: the current one) and swap it in if it fits the cameras.

        The camera-moved checks start afresh with the next frame set (``CameraWatch`` sees a
        new runtime): a new model comes with new floor marks.
        """
        path = Path(model_dir) if model_dir is not None else self.model_dir
        if path is None:
            raise MomlocError("no model directory configured")
        runtime = self._load_runtime(path)  # MomRuntime.load runs the model once
        problem = self._incompatibility(runtime)
        if problem is not None:
            raise MomlocError(f"{path}: {problem}; keeping the current model")
        self.runtime, self.model_dir = runtime, path
        self.chain.new_model()  # offsets of the former model's localizer do not carry over
        if self.error and self.error.startswith("model"):
            self.error = None
        log.info("model loaded from %s", path)
        return self.model_info()

    def reset_alignment(self) -> None:
        """Accept the cameras where they are now: new error baseline and image references."""
        self.camera_watch.reset()

    def alignment_status(self, names: Sequence[str] | None = None) -> list[CameraMoved]:
        """Per camera: image shift and reprojection error combined into one moved verdict."""
        return self.camera_watch.status(names)

    def model_info(self) -> dict[str, Any]:
        runtime = self.runtime
        if runtime is None:
            return {"loaded": False, "path": str(self.model_dir) if self.model_dir else None}
        problem = self._incompatibility(runtime)
        return {
            "loaded": True,
            "path": str(self.model_dir) if self.model_dir else None,
            "num_cameras": int(runtime.num_cameras),
            "image_sizes": np.asarray(runtime.image_sizes).astype(int).tolist(),
            "observation": runtime.observation,
            "compatible": problem is None,
            "problem": problem,
        }

    # -- introspection ---------------------------------------------------------------------------

    def view(self, camera: int) -> CameraView:
        return self.previews.view(camera)

    def stats(self) -> dict[str, Any]:
        """Frame rate over the last ~4 s, latency percentiles, stage timings, counters."""
        return {
            "running": self.running,
            **self.throughput.stats(),
            "detection": self.detect.stats(),
            "seq": self._seq,
            "frames_processed": self.frames_processed,
            "frames_dropped": self.frames_dropped,
            "views_left_out": self.views_left_out,
            "error": self.error,
            "failures": self.failures,
            "last_failure": self.last_failure,
        }


POSTURES: dict[str, Literal["standing", "sitting", "lying"]] = {
    "standing": "standing",
    "sitting": "sitting",
    "lying": "lying",
}


def served_person(track: Track) -> Person:
    """A track as the snapshot serves it (the fall bench feeds the same dicts to its detector)."""
    person: Person = {
        "id": int(track.id),
        "x": round(float(track.x), 4),
        "y": round(float(track.y), 4),
        "vx": round(float(track.vx), 4),
        "vy": round(float(track.vy), 4),
        "confidence": round(float(np.clip(track.confidence, 0.0, 1.0)), 3),
        "cameras": [int(k) for k in track.cameras],
    }
    if not served_inside(track):  # served flagged (tracking.outside_area: flag)
        person["outside"] = True
    posture = track.posture
    if posture and posture[0] in POSTURES:  # service.tracking.posture; absent: unknown
        person["posture"] = POSTURES[posture[0]]
        person["posture_confidence"] = round(float(posture[1]), 3)
    return person


def _load_mom_runtime(path: Path) -> LocalizationModel:
    from models.mom.runtime import MomRuntime

    return MomRuntime.load(path)
