"""Detection scheduling: publish every frame set at the cameras' rate, detect when there is time.

Why: two 640x480 frames through SSDLite cost ~42 CPU-ms on one onnxruntime thread (~51 on two,
~30 ms wall), while a 30 fps camera gives a 33 ms slot and the rest of the chain (association,
MoM, tracking, publishing) and the cameras need CPU too. Run inline on every frame set, the
daemon fell to 23-25 fps with p95 capture->publish 77-102 ms on an idle host. No fixed
"every n-th frame set" fits every machine and load, and a detection run inline on *some* frame
sets makes exactly those frame sets late (their latency is the detector's), which is what the
p95 measures.

Design (``mode="auto"``):

- **The detector runs beside the pipeline, never in front of it.** One background worker holds
  at most one job; when it is free, the *newest* frame set is handed to it (never an older one,
  never a queue: :class:`ThreadRunner` refuses a second job). The frame set that was handed over
  is published at once like any other, with carried boxes.
- **Boxes are carried between detections** by :class:`service.detection.box_carrier.BoxCarrier`
  (Kalman filter on boxes + Lucas-Kanade flow inside them), one per camera. A finished detection
  describes a frame that is now 1-3 frames old; the carrier matches it against its own boxes *at
  that frame's time* and applies the correction to the current boxes, so the result is used for the
  newest frame set and nothing is processed late.
- **Adaptive to measured cost.** The detector's wall time per call is measured (exponential
  average); with ``max_duty < 1`` the next job waits ``cost * (1 / max_duty - 1)`` after the
  last one finished, leaving that share of time to the rest of the machine. The detection rate
  therefore follows whatever the detector costs on this machine under its current load.
- **The detector yields.** Its thread runs at ``nice`` 10 and, in the daemon, on one
  onnxruntime thread (which computes on the calling thread, so all of it runs at that priority),
  leaving the other core to the cameras and the pipeline.
- **Flow only when there is time.** A camera frame is carried by the filter alone when its
  frame set reaches the stage already later than ``flow_max_lag_s`` (15 ms), or while flow has
  been costing more than ``flow_budget_s`` (5 ms) per camera frame (re-measured every 30th frame
  set): on an idle 2-core host flow cost 2-4 ms per camera frame, at load 8 10-20 ms.
- ``cameras_per_call=1`` alternates cameras (one frame per call, round-robin, oldest-refreshed
  first) instead of one batched call for all: shorter jobs, fresher corrections, one call's
  overhead per camera.
- Every box says how it was obtained: :class:`service.detection.box_carrier.CarriedDetections` adds
  ``age`` (seconds since the detector found it; 0 = found in this frame) to the public
  ``Detections`` fields, available per camera in :attr:`DetectionScheduler.last`. A carried box
  expires after ``max_age_s`` without a detection, stretched to 2.5 times the interval between
  two detections of its camera when the detector is slower, so boxes do not vanish just because
  the detector is slow.

Measured (``bench/serving/realtime.py``, 2 cores shared with other jobs, figures in
``bench/results/realtime.md``, run with the load rising from 3 to 12): on drawn frames the
daemon published 28.9 fps with p95 capture->publish 29.9 ms with scheduling (0.96x the fps of
the same pipeline fed the simulator's boxes; its p95 10.9 ms), against 13.2 fps and p95 171 ms
detecting every frame set; on ``vtest.avi`` 28.0 fps, p95 66 ms (0.95x; the pipeline fed
replayed boxes had p95 38 ms there), against 5.8 fps, p95 311 ms. The detector at normal
priority: 29.1 / 24.7 fps, p95 48 / 86 ms. On an idle host (short run) scheduling gave 30 fps
with p95 15 ms (drawn) and 29 ms (video).

``mode="every_frame"`` is the old behaviour: one inline batched call per frame set, ages 0.

Rejected: inline detection every n-th frame set (those frame sets are late by the detector's
time, and the next frames are dropped while it runs: fps and p95 both suffer); a queue of frame
sets for the detector (latency grows without bound when the detector is slower than the
cameras); crops around known people *instead of* full-frame detection (nobody new would ever be
found). Crops *after* a full pass are the optional ``refiner``
(:class:`models.detector.windows.WindowRefiner`, NanoDet takes any input size and batch): every
window of a job in one call, off by default because each costs ~7 CPU-ms and so slows the
detection rate (``bench/results/small_people.md``). Measured figures: ``bench/results/realtime.md``.

Time: :class:`DeferredRunner` runs the detector at once but releases its result only when an
injectable clock passes ``start + cost``, so tests (and offline replays) see exactly the
schedule a detector of that cost would get, whatever the machine's load.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np

from capture.rig import FrameSet
from models.detector.base import Detections, PersonDetector
from models.detector.windows import WindowRefiner
from service.detection.box_carrier import BoxCarrier, CarriedDetections

log = logging.getLogger("momloc.detection")

Mode = Literal["auto", "every_frame"]


@dataclass(frozen=True)
class DetectionJob:
    """Frames handed to the detector together: ``(camera, capture time, BGR image)`` each, and
    per frame the boxes carried there when the job was made (``priors``: where known people are,
    for the window refiner; empty tuple when not needed)."""

    frames: tuple[tuple[int, float, np.ndarray], ...]
    priors: tuple[np.ndarray, ...] = ()

    @property
    def images(self) -> list[np.ndarray]:
        return [frame[2] for frame in self.frames]


JobDetect = Callable[[DetectionJob], list[Detections]]


@dataclass(frozen=True)
class JobResult:
    job: DetectionJob
    detections: list[Detections] | None
    cost_s: float
    error: BaseException | None = None


class Runner(Protocol):
    """Runs at most one detection job at a time, never a queue of them."""

    def busy(self) -> bool: ...
    def submit(self, job: DetectionJob) -> None: ...
    def poll(self) -> JobResult | None: ...
    def close(self) -> None: ...


class ThreadRunner:
    """One background thread, one job slot. ``nice`` > 0 lowers that thread's priority (Linux:
    per thread), so when cores are short the pipeline and cameras run first; onnxruntime with one
    intra-op thread computes on the calling thread, so the whole detector runs at that priority."""

    def __init__(self, detect: JobDetect, nice: int = 0):
        self._detect, self._nice = detect, int(nice)
        self._job: DetectionJob | None = None
        self._result: JobResult | None = None
        self._cond = threading.Condition()
        self._closed = True
        self._thread: threading.Thread | None = None

    def busy(self) -> bool:
        with self._cond:
            return self._job is not None or self._result is not None

    def submit(self, job: DetectionJob) -> None:
        with self._cond:
            if self._job is not None or self._result is not None:
                raise RuntimeError("detector busy: a job is never queued behind another")
            if self._closed:  # first job, or the pipeline was restarted after close()
                self._closed = False
                self._thread = threading.Thread(
                    target=self._run, name="momloc-detector", daemon=True
                )
                self._thread.start()
            self._job = job
            self._cond.notify_all()

    def poll(self) -> JobResult | None:
        with self._cond:
            result, self._result = self._result, None
            return result

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=5)
        with self._cond:
            self._job = self._result = None

    def _run(self) -> None:
        if self._nice > 0:
            try:
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), self._nice)
            except (OSError, AttributeError):  # not Linux, or not allowed: run at normal priority
                log.info("detector thread priority unchanged")
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._job is not None or self._closed)
                if self._closed:
                    return
                job = self._job
            assert job is not None
            start = time.perf_counter()
            detections, error = None, None
            try:
                detections = self._detect(job)
            except Exception as failure:  # handed to the pipeline thread, which reports it
                error = failure
            result = JobResult(job, detections, time.perf_counter() - start, error)
            with self._cond:
                self._job, self._result = None, result


class DeferredRunner:
    """Runs each job at submit time but releases the result only once ``clock() >= start +
    cost``; ``cost(job)`` models the detector's time (tests, offline replays)."""

    def __init__(
        self,
        detect: JobDetect,
        clock: Callable[[], float],
        cost: Callable[[DetectionJob], float],
    ) -> None:
        self._detect, self._clock, self._cost = detect, clock, cost
        self._pending: tuple[float, JobResult] | None = None

    def busy(self) -> bool:
        return self._pending is not None

    def submit(self, job: DetectionJob) -> None:
        if self._pending is not None:
            raise RuntimeError("detector busy: a job is never queued behind another")
        cost = float(self._cost(job))
        result = JobResult(job, self._detect(job), cost)
        self._pending = (self._clock() + cost, result)

    def poll(self) -> JobResult | None:
        if self._pending is None or self._clock() < self._pending[0]:
            return None
        result, self._pending = self._pending[1], None
        return result

    def close(self) -> None:
        self._pending = None


class DetectionScheduler:
    """The detection stage (``service.stages.DetectStage``) in either mode:
    ``scheduler(frame_set) -> [CarriedDetections per camera]``; ``every_frame`` detects inline,
    ``auto`` beside the pipeline (module docstring).

    ``runner`` defaults to a :class:`ThreadRunner` (``nice``) around ``detector.detect``;
    ``clock`` (seconds, monotonic) times the duty cycle and must be the runner's clock when a
    :class:`DeferredRunner` is injected; ``wall`` (the frames' clock) measures how late a frame
    set arrives, for ``flow_max_lag_s``. ``carrier`` options go to every camera's
    :class:`BoxCarrier`. Boxes are used as the detector returns them: its own
    ``score_threshold`` (from ``detector.score_threshold`` in the settings) is the one filter.
    """

    def __init__(
        self,
        detector: PersonDetector,
        *,
        mode: Mode = "auto",
        max_duty: float = 1.0,
        cameras_per_call: int = 0,
        nice: int = 10,
        runner: Runner | None = None,
        clock: Callable[[], float] = time.perf_counter,
        wall: Callable[[], float] = time.time,
        flow_max_lag_s: float = 0.015,
        flow_budget_s: float = 0.005,
        carrier: dict[str, Any] | None = None,
        refiner: WindowRefiner | None = None,
    ) -> None:
        if mode not in ("auto", "every_frame"):
            raise ValueError(f"detection schedule {mode!r}: choose auto or every_frame")
        if not 0.0 < max_duty <= 1.0:
            raise ValueError("max_duty must be in (0, 1]")
        self.detector, self.mode = detector, mode
        self.refiner = refiner
        self.max_duty, self.cameras_per_call = float(max_duty), int(cameras_per_call)
        self.clock, self.wall, self.flow_max_lag_s = clock, wall, float(flow_max_lag_s)
        self.flow_budget_s = float(flow_budget_s)
        self.flow_cost_s: float | None = None  # average time of one camera frame carried by flow
        self._carrier_options = dict(carrier or {})
        self._max_age_s = float(self._carrier_options.get("max_age_s", 0.5))
        self._flow = bool(self._carrier_options.get("flow", True))
        self.carriers: list[BoxCarrier] = []
        self.runner: Runner | None = None
        if mode == "auto":
            self.runner = runner or ThreadRunner(self.detect_job, nice=nice)
        self.last: list[CarriedDetections] = []
        self.cost_s: float | None = None  # exponential average of the detector's time per call
        self._next_allowed = -np.inf
        self._refreshed: dict[int, float] = {}  # camera -> clock time of its last detection job
        self.frame_sets = 0
        self.flow_skipped = 0  # camera frames carried by the filter alone: the set came late
        self.jobs = 0
        self.frames_detected = 0
        self.boxes_out = 0
        self.age_sum = 0.0  # seconds, over published boxes

    # -- the stage ---------------------------------------------------------------------------------

    def detect_job(self, job: DetectionJob) -> list[Detections]:
        """The detector on a job's frames, then (with a refiner) a second look in windows
        around the known small people (``bench/results/small_people.md``)."""
        found = self.detector.detect(job.images)
        if self.refiner is not None and job.priors:
            found = self.refiner(job.images, found, job.priors)
        return found

    @property
    def keypoints(self) -> bool:
        """Whether the detector adds COCO-17 keypoints
        (``models.detector.keypoints.KeypointDetector``): a keypoint model reads them downstream."""
        return bool(self.detector.keypoints)

    def __call__(self, frame_set: FrameSet) -> list[CarriedDetections]:
        """Boxes for every camera of ``frame_set`` (the newest), detected or carried."""
        frames = list(frame_set.frames)
        self.frame_sets += 1
        out = self._inline(frames) if self.mode == "every_frame" else self._scheduled(frames)
        self.last = out
        self.boxes_out += sum(len(d) for d in out)
        self.age_sum += sum(float(np.sum(d.age)) for d in out if d.age is not None)
        return out

    def _inline(self, frames: Sequence[Any]) -> list[CarriedDetections]:
        out = [CarriedDetections.empty() for _ in frames]
        present = [k for k, f in enumerate(frames) if f is not None and f.image is not None]
        if not present:
            return out
        start = self.clock()
        results = self.detector.detect([frames[k].image for k in present])
        self._measured(self.clock() - start)
        self.jobs += 1
        self.frames_detected += len(present)
        for k, det in zip(present, results, strict=True):
            boxes = np.asarray(det.boxes, np.float32).reshape(-1, 4)
            out[k] = CarriedDetections(
                boxes,
                np.asarray(det.scores, np.float32),
                None if det.keypoints is None else np.asarray(det.keypoints),
                np.zeros(len(boxes), np.float32),
            )
        return out

    def _scheduled(self, frames: Sequence[Any]) -> list[CarriedDetections]:
        assert self.runner is not None
        while len(self.carriers) < len(frames):
            self.carriers.append(BoxCarrier(**self._carrier_options))
        result = self.runner.poll()
        if result is not None:
            self._apply(result)
        out = []
        for k, frame in enumerate(frames):
            carrier = self.carriers[k]
            if frame is None:
                out.append(CarriedDetections.empty())
            elif carrier.time is not None and abs(frame.timestamp - carrier.time) < 1e-9:
                out.append(carrier.current())  # this camera has no newer frame
            else:
                image = frame.image if self._flow_affordable(frame) else None
                self.flow_skipped += image is None and frame.image is not None
                start = self.clock()
                out.append(carrier.advance(float(frame.timestamp), image))
                if image is not None and self._flow:
                    cost = self.clock() - start
                    ema = self.flow_cost_s
                    self.flow_cost_s = cost if ema is None else 0.8 * ema + 0.2 * cost
        now = self.clock()
        if not self.runner.busy() and now >= self._next_allowed:
            job = self._job(frames, out)
            if job is not None:
                self.runner.submit(job)
                self.jobs += 1
                self.frames_detected += len(job.frames)
                for camera, _, _ in job.frames:
                    self._refreshed[camera] = now
        return out

    def _flow_affordable(self, frame: Any) -> bool:
        """Flow for this camera frame unless the set is already late or flow has been costing
        more than its budget (re-measured on every 30th frame set, as load changes)."""
        if not self._flow or frame.image is None:
            return frame.image is not None  # flow off: the image only bounds the boxes
        if self.wall() - frame.timestamp > self.flow_max_lag_s:
            return False
        cost = self.flow_cost_s
        return cost is None or cost <= self.flow_budget_s or self.frame_sets % 30 == 0

    def _job(
        self, frames: Sequence[Any], carried: Sequence[CarriedDetections]
    ) -> DetectionJob | None:
        present = [k for k, f in enumerate(frames) if f is not None and f.image is not None]
        if not present:
            return None
        if 0 < self.cameras_per_call < len(present):
            present = sorted(present, key=lambda k: (self._refreshed.get(k, -np.inf), k))
            present = sorted(present[: self.cameras_per_call])
        priors = tuple(carried[k].boxes for k in present) if self.refiner is not None else ()
        return DetectionJob(
            tuple((k, float(frames[k].timestamp), frames[k].image) for k in present), priors
        )

    def _apply(self, result: JobResult) -> None:
        self._measured(result.cost_s)
        wait = result.cost_s * (1.0 / self.max_duty - 1.0)
        self._next_allowed = self.clock() + wait
        if result.error is not None:
            raise RuntimeError(f"detector: {result.error}") from result.error
        assert result.detections is not None
        # a box must outlive the time the detector takes to look again, or a slow detector's
        # boxes would all expire between its calls
        period = (self.cost_s or 0.0) / self.max_duty
        if 0 < self.cameras_per_call < len(self.carriers):  # each camera's turn comes less often
            period *= -(-len(self.carriers) // self.cameras_per_call)
        for carrier in self.carriers:
            carrier.max_age_s = max(self._max_age_s, 2.5 * period)
        for (camera, t, _), det in zip(result.job.frames, result.detections, strict=True):
            self.carriers[camera].correct(t, det.boxes, det.scores, det.keypoints)

    def _measured(self, cost: float) -> None:
        self.cost_s = cost if self.cost_s is None else 0.8 * self.cost_s + 0.2 * cost

    # -- service -----------------------------------------------------------------------------------

    def stats(self) -> dict[str, Any]:
        """For ``/v1/health``: schedule, detector cost, share of frames detected, mean box age."""
        sets = max(self.frame_sets, 1)
        cameras = max(len(self.last), 1)
        return {
            "schedule": self.mode,
            "detector_ms": None if self.cost_s is None else round(self.cost_s * 1e3, 2),
            "detected_share": round(self.frames_detected / (sets * cameras), 3),
            "box_age_ms": round(self.age_sum / max(self.boxes_out, 1) * 1e3, 1),
            "jobs": self.jobs,
            "flow_ms": None if self.flow_cost_s is None else round(self.flow_cost_s * 1e3, 2),
            "flow_skipped_share": round(self.flow_skipped / (sets * cameras), 3),
        }

    def close(self) -> None:
        if self.runner is not None:
            self.runner.close()
