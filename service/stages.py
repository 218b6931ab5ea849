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
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from capture.rig import FrameSet
from models.detector.base import Detections
from models.geometry.floor_prior import FloorPrior
from service.snapshot import Snapshot

__all__ = [
    "AreaAware",
    "AssociateStage",
    "Association",
    "Closeable",
    "DetectStage",
    "Detections",
    "FloorViewing",
    "FrameListener",
    "FrameResult",
    "FrameSet",
    "LocalizationModel",
    "Origin",
    "Reprojecting",
    "Snapshot",
    "Stored",
    "Track",
    "TrackAnchor",
    "TrackStage",
    "Unscheduled",
    "WithCovariance",
    "WorldBounds",
]


@dataclass(frozen=True)
class Origin:
    """Where one position handed to the tracker came from (:meth:`TrackStage.update`); the
    track it feeds keeps the fields (:class:`Track`).

    ``cameras``: the cameras that saw it; ``frame``: the snapshot ``seq`` of its frame set;
    ``association``: its index in that frame set's associations (the lone-view correction and
    :meth:`FrameResult.track_ids` find it there); ``cost``: the association's reprojection cost;
    ``inside``: in the model's set-up area (``service.pipeline.chain``); ``boxes``: the
    association's boxes [K, 4] (NaN where camera k does not see it), for the tracker's image
    continuity (``service.tracking.image_continuity``); ``standing``: false when its boxes read
    lying: the tracker trusts a lying body's position only as far as its starting measurement
    scale (``service.tracking.noise_scale``).
    """

    cameras: tuple[int, ...] = ()
    frame: int | None = None
    association: int | None = None
    cost: float | None = None
    inside: bool = True
    boxes: np.ndarray | None = field(default=None, compare=False)
    standing: bool = True


@dataclass
class Track:
    """One person as reported to clients (positions in metres, velocities in m/s).

    ``cameras`` are the cameras measuring it now (none while coasting); ``frame``,
    ``association``, ``cost`` and ``inside`` come from the :class:`Origin` of the position
    that last fed it.
    """

    id: int
    x: float
    y: float
    vx: float
    vy: float
    confidence: float
    cameras: list[int] = field(default_factory=list)
    coasting: bool = False
    age_s: float = 0.0
    frame: int | None = None
    association: int | None = None
    cost: float | None = None
    inside: bool = True
    # (label, confidence) of service.tracking.posture, set by the chain; None: not judged
    posture: tuple[str, float] | None = None


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


@dataclass(frozen=True)
class TrackAnchor:
    """A held track predicted to the time of the frame set being associated: where the
    association expects a person it already tracks (``service.tracking.association``'s
    track-driven step, fed by ``service.tracking.tracker.Tracker.anchors``).

    ``xy`` [2] m and ``cov`` [2, 2] m²: the predicted floor position and its covariance.
    ``image_x`` [K'] px and ``image_std`` [K'] px (optional; K' ≤ K cameras, the rest unknown;
    NaN where camera k has not seen the track within ``image_continuity.MAX_AGE_S``): each
    camera's predicted box centre of the track and its std (``ViewMemory.predict``), for the
    association's per-camera box continuity. ``unseen_s``: seconds from the last frame set a
    camera saw the track in to the time it is predicted to, for the lone-view continuity
    reading (``service.tracking.posture_continuity``). ``track_id``: the track it anchors
    (None: unknown), so that reading tells one person's anchors from another's.
    """

    xy: np.ndarray
    cov: np.ndarray
    image_x: np.ndarray | None = None
    image_std: np.ndarray | None = None
    unseen_s: float = 0.0
    track_id: int | None = None


class Reprojecting(Protocol):
    """The decoder: floor positions [N, 2] -> each camera's pixel [N, K, 2] of the body's mean
    point, with the cameras' image sizes [K, 2] (coverage, lines of sight)."""

    @property
    def image_sizes(self) -> np.ndarray: ...

    def reproject(self, world: np.ndarray) -> np.ndarray: ...


class Coverage(Protocol):
    """Which cameras [N, K] bool should see a person at floor positions [N, 2]; ``lying`` [N]
    bool (optional): those rows are a body on the floor, which a camera sees only where it sees
    the floor there (:func:`service.tracking.view_geometry.covering_cameras`)."""

    def __call__(self, world: np.ndarray, lying: np.ndarray | None = None, /) -> np.ndarray: ...


class WithCovariance(Protocol):
    """Covariance [B, 2, 2] (m²) of each tuple's floor position; NaN rows where the model
    cannot tell (then the tracker's per-view default applies)."""

    def covariance(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray: ...


class FloorViewing(Protocol):
    """Each camera's own floor estimate [B, K, 2] of a tuple's boxes and its information
    [B, K, 2, 2] (association's floor test), or None for a model without floor geometry."""

    def floor_views(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray] | None: ...


class AreaAware(Protocol):
    """[B] bool: positions [B, 2] of tuples [B, K, 4] inside the area the model was set up on
    (all True for a model without one)."""

    def inside(self, boxes: np.ndarray, world: np.ndarray) -> np.ndarray: ...


class Stored(Protocol):
    """Where a model came from: its directory and ``model.json`` (the self-learning room keys
    its labels by the floor marks recorded there) and its fitted floor geometry (None: none)."""

    @property
    def model_dir(self) -> Path: ...

    @property
    def meta(self) -> dict[str, Any]: ...

    @property
    def floor_prior(self) -> FloorPrior | None: ...


WorldBounds = tuple[tuple[float, float], tuple[float, float]]
"""((xmin, ymin), (xmax, ymax)) metres: the floor the training positions cover."""


class LocalizationModel(Reprojecting, WithCovariance, FloorViewing, AreaAware, Stored, Protocol):
    """What the chain and the pipeline need from ``models.mom.runtime.MomRuntime``.

    ``observation`` is ``"bbox"`` or ``"keypoints"`` (``model.json``); keypoint models need
    ``keypoints`` [B, K, J, 3] beside the boxes in every call.

    The capabilities are small Protocols of their own, so a function asks for just the one it
    uses (``covering_cameras`` a :class:`Reprojecting`, the set-up area gate an
    :class:`AreaAware`) and a test double for it implements only that. A model has all of
    them: what a model file lacks (no fitted floor prior, no set-up area, no stored bounds) is
    settled when it is loaded and answered by the capability itself (None, NaN, all inside),
    so no caller probes for a method.
    """

    @property
    def num_cameras(self) -> int: ...

    @property
    def observation(self) -> str: ...

    @property
    def world_bounds(self) -> WorldBounds | None: ...

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray: ...

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray: ...


class DetectStage(Protocol):
    """Frame set -> one :class:`Detections` per camera (empty for a camera without a frame).

    ``keypoints``: whether the detections carry COCO-17 keypoints (required by keypoint models);
    ``stats``: the detection schedule's counters for ``/v1/health`` (None without one);
    ``close``: stops a worker thread the stage runs, if any.
    """

    @property
    def keypoints(self) -> bool: ...

    def __call__(self, frame_set: FrameSet) -> Sequence[Detections]: ...

    def stats(self) -> dict[str, Any] | None: ...

    def close(self) -> None: ...


class Unscheduled:
    """The part of :class:`DetectStage` a stage without a detection schedule shares (the
    simulator's boxes, recorded detections): no counters to report, no thread to stop."""

    def stats(self) -> None:
        return None

    def close(self) -> None:
        return None


class AssociateStage(Protocol):
    """Detections of all cameras -> people (``service.tracking.association.associate``)."""

    def __call__(
        self,
        detections: Sequence[Detections],
        runtime: LocalizationModel,
        /,
        *,
        max_error_px: float,
        anchors: Sequence[TrackAnchor] = (),
    ) -> list[Association]: ...


class TrackStage(Protocol):
    """Positions of one instant -> persistent tracks (``service.tracking.tracker.Tracker``)."""

    def update(
        self,
        t: float,
        positions: np.ndarray,
        origins: Sequence[Origin] | None = None,
        covariances: Sequence[np.ndarray | None] | np.ndarray | None = None,
        coverage: Coverage | None = None,
    ) -> list[Track]: ...


@dataclass(frozen=True)
class FrameResult:
    """Everything one frame set produced, handed to every listener after publishing.

    ``frames``: the frame set as it came from the rig (stale frames included, for previews);
    ``fused``: per camera, whether its frame took part in detection and association (False for
    no frame or a frame left out by the skew rule); ``timings_ms``: per stage wall time.
    ``runtime`` is the model that localized this set (None without one), so a listener judging
    reprojection errors uses the same model the positions came from. ``outside``: the
    associations beyond the model's set-up area that the chain kept out of tracking
    (``tracking.outside_area: drop``; the learning room may still learn from them,
    :mod:`service.learning.labels`).
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
    outside: list[Association] = field(default_factory=list)

    def track_ids(self) -> dict[tuple[int, int], int]:
        """``(camera, detection index) -> track id`` for the detections tracked in this set."""
        ids: dict[tuple[int, int], int] = {}
        for track in self.tracks:
            if track.frame != self.snapshot.seq or track.association is None:
                continue  # a coasting track: not measured in this frame set
            association = self.associations[track.association]
            for camera, index in enumerate(association.detection_index):
                if index is not None:
                    ids[(camera, int(index))] = int(track.id)
        return ids


FrameListener = Callable[[FrameResult], None]


@runtime_checkable
class Closeable(Protocol):
    """A listener that holds a thread or pending writes: the pipeline closes it when it stops."""

    def close(self) -> None: ...
