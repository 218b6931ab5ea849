"""The typed values passed between the live pipeline's stages, defined once.

One frame set flows through the chain as::

    FrameSet                      capture.rig: newest frame per camera, capture times, skew
      -> list[Detections]         per camera: boxes [M, 4], scores [M], keypoints [M, 17, 3] | None
      -> list[Association]        per person: one detection (or none) per camera, floor position
      -> list[Track]              persistent id, position, velocity, confidence, cameras
      -> Snapshot                 the wire JSON (service.pipeline.hub)

and :class:`FrameResult` bundles all of them (plus stage timings) for the listeners that hang
off the pipeline (camera-moved checks, previews, statistics, the set-up recorder): each gets the
whole result of a frame set once, after it was published, and none can change what is published.

Why the detection stage returns :class:`~models.detector.base.Detections` (not bare box
arrays): a model trained with ``--observation keypoints`` needs each box's COCO-17 keypoints,
and an earlier pipeline that passed boxes only silently threw them away. A stage says whether it
delivers keypoints (:attr:`DetectStage.keypoints`), so a keypoint model on a box-only detector is
refused at load instead of failing on every frame.

The stages are Protocols so the real ones (``service.detection.schedule.DetectionScheduler``,
the demo's ``SimulatedDetections``, ``service.tracking.association.associate``,
``service.tracking.tracker.Tracker``) and tests' doubles are interchangeable without inheriting
from anything.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from capture.rig import FrameSet
from models.detector.base import Detections
from service.snapshot import Snapshot

__all__ = [
    "AssociateStage",
    "Association",
    "DetectStage",
    "Detections",
    "FrameListener",
    "FrameResult",
    "FrameSet",
    "LocalizationModel",
    "Snapshot",
    "Track",
    "TrackStage",
]


@dataclass
class Track:
    """One person as reported to clients (positions in metres, velocities in m/s)."""

    id: int
    x: float
    y: float
    vx: float
    vy: float
    confidence: float
    cameras: list[int] = field(default_factory=list)
    coasting: bool = False
    age_s: float = 0.0
    meta: dict[str, Any] = field(default_factory=dict)


@dataclass
class Association:
    """One person: a box (or NaN) per camera and the model's floor position for that tuple."""

    boxes: np.ndarray  # [K, 4] pixels, NaN where camera k does not see the person
    cameras: list[int]  # cameras that see the person
    world: np.ndarray  # [2] metres
    cost: float  # RMS normalised reprojection error over the seen cameras
    # (service.tracking.association)
    detection_index: list[int | None]  # per camera: index into that camera's detections
    errors: np.ndarray = field(default_factory=lambda: np.zeros(0))  # [K] px, NaN where unseen
    covariance: np.ndarray | None = None  # [2, 2] m² of ``world`` when the model gives one
    keypoints: np.ndarray | None = None  # [K, J, 3] for keypoint models, NaN where unseen
    inside: bool = (
        True  # in the model's set-up area (service.pipeline.chain; models.mom.setup_area)
    )


class LocalizationModel(Protocol):
    """What association and the pipeline need from ``models.mom.runtime.MomRuntime``.

    ``observation`` is ``"bbox"`` or ``"keypoints"`` (``model.json``); keypoint models need
    ``keypoints`` [B, K, J, 3] beside the boxes in every call.
    """

    @property
    def num_cameras(self) -> int: ...

    @property
    def image_sizes(self) -> np.ndarray: ...

    @property
    def observation(self) -> str: ...

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray: ...

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray: ...


class DetectStage(Protocol):
    """Frame set -> one :class:`Detections` per camera (empty for a camera without a frame).

    ``keypoints``: whether the detections carry COCO-17 keypoints (required by keypoint models).
    """

    @property
    def keypoints(self) -> bool: ...

    def __call__(self, frame_set: FrameSet) -> list[Detections]: ...


class AssociateStage(Protocol):
    """Detections of all cameras -> people (``service.tracking.association.associate``)."""

    def __call__(
        self,
        detections: Sequence[Detections],
        runtime: LocalizationModel,
        /,
        *,
        max_error_px: float,
    ) -> list[Association]: ...


class TrackStage(Protocol):
    """Positions of one instant -> persistent tracks (``service.tracking.tracker.Tracker``)."""

    def update(
        self,
        t: float,
        positions: np.ndarray,
        meta: list[dict[str, Any]] | None = None,
        covariances: Sequence[np.ndarray | None] | np.ndarray | None = None,
        coverage: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> list[Track]: ...


@dataclass(frozen=True)
class FrameResult:
    """Everything one frame set produced, handed to every listener after publishing.

    ``frames``: the frame set as it came from the rig (stale frames included, for previews);
    ``fused``: per camera, whether its frame took part in detection and association (False for
    no frame or a frame left out by the skew rule); ``timings_ms``: per stage wall time.
    ``runtime`` is the model that localized this set (None without one), so a listener judging
    reprojection errors uses the same model the positions came from.
    """

    frame_set: FrameSet
    t_capture: float
    fused: list[bool]
    detections: list[Detections]
    associations: list[Association]
    tracks: list[Track]
    snapshot: Snapshot
    runtime: LocalizationModel | None
    timings_ms: dict[str, float]

    def track_ids(self) -> dict[tuple[int, int], int]:
        """``(camera, detection index) -> track id`` for the detections tracked in this set."""
        ids: dict[tuple[int, int], int] = {}
        for track in self.tracks:
            meta = track.meta or {}
            if meta.get("frame") != self.snapshot.seq:
                continue  # a coasting track: not measured in this frame set
            association = self.associations[meta["association"]]
            for camera, index in enumerate(association.detection_index):
                if index is not None:
                    ids[(camera, int(index))] = int(track.id)
        return ids


FrameListener = Callable[[FrameResult], None]
