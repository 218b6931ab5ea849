"""The real detection stage: the person detector on a frame set, or its scheduler.

``DetectorStage`` is what ``service.stages.DetectStage`` means in the daemon: one batched
detector call for all cameras (``detection.schedule: every_frame``), or the
``service.detection.schedule.DetectionScheduler`` that runs the detector beside the pipeline and
carries boxes in between (``auto``). Boxes are kept as the detector returns them (its own
``score_threshold`` is the one filter), each with its keypoints: a keypoint model reads them
downstream.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from capture.rig import FrameSet
from capture.worker import Frame
from models.detector.base import Detections, PersonDetector


class DetectionSchedule(Protocol):
    """``service.detection.schedule.DetectionScheduler`` as the detector stage uses it."""

    def step(self, frame_set: FrameSet) -> Sequence[Detections]: ...
    def stats(self) -> dict[str, Any]: ...
    def close(self) -> None: ...


class Unscheduled:
    """The part of ``service.stages.DetectStage`` a stage without a detection schedule shares
    (the simulator's boxes, recorded detections): no counters to report, no thread to stop."""

    def stats(self) -> None:
        return None

    def close(self) -> None:
        return None


class DetectorStage:
    """Real detector: one batched call for all cameras, keypoints kept with their boxes.

    With ``schedule`` (a ``service.detection.schedule.DetectionScheduler``) the scheduler runs
    the detector beside the pipeline and carries boxes (and their keypoints) between detections.
    """

    def __init__(self, detector: PersonDetector, schedule: DetectionSchedule | None = None) -> None:
        self.detector = detector
        self.schedule = schedule

    @property
    def keypoints(self) -> bool:
        """Whether the detector adds COCO-17 keypoints
        (``models.detector.keypoints.KeypointDetector``)."""
        return bool(self.detector.keypoints)

    def stats(self) -> dict[str, Any] | None:
        return None if self.schedule is None else self.schedule.stats()

    def close(self) -> None:
        if self.schedule is not None:
            self.schedule.close()

    def __call__(self, frame_set: FrameSet) -> list[Detections]:
        if self.schedule is not None:
            return list(self.schedule.step(frame_set))
        frames = list(frame_set.frames)
        present = [k for k, f in enumerate(frames) if f is not None and f.image is not None]
        out = [Detections.empty() for _ in frames]
        if not present:
            return out
        results = self.detector.detect([_image(frames[k]) for k in present])
        for k, det in zip(present, results, strict=True):
            out[k] = Detections(
                np.asarray(det.boxes, np.float32).reshape(-1, 4),
                np.asarray(det.scores, np.float32),
                None if det.keypoints is None else np.asarray(det.keypoints),
            )
        return out


def _image(frame: Frame | None) -> np.ndarray:
    assert frame is not None and frame.image is not None
    return frame.image
