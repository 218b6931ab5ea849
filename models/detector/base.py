"""Person detector interface, result type, registry and the shared onnxruntime session set-up.

Design (after Frigate's detector plugins): a detector type is one module implementing
:class:`PersonDetector` and registering itself under a ``kind`` name; the service picks it by that
name from settings through :func:`create_detector`. Every detector

- takes a *batch* of BGR frames (one per camera, any sizes) and runs **one** onnxruntime call for
  all of them, because per-call overhead dominates on 2 cores;
- returns boxes in the **original frame's pixels** (xmin, ymin, xmax, ymax) with scores, so callers
  never see the network's input geometry;
- validates its model and runs a warm-up inference at load, so a wrong or corrupt file fails at
  start with one :class:`~common.errors.MomlocError` line instead of on the first frame.

Settings (after Frigate's per-plugin config): each plugin module also defines its settings class,
a subclass of :class:`DetectorSettingsBase` with a ``kind: Literal[...]`` tag and only the options
that kind takes, so the daemon's settings are a union discriminated by ``kind`` and a wrong option
is a validation error naming the field, not a failure at start.

Example::

    from models.detector import create_detector
    detector = create_detector("ssdlite", score_threshold=0.5)
    detections = detector.detect([frame_cam0, frame_cam1])
    detections[0].boxes  # [M, 4] float32 pixels of frame_cam0
"""

from __future__ import annotations

import hashlib
import inspect
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Protocol, runtime_checkable

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from common.errors import MomlocError


@dataclass(frozen=True, eq=False)
class Detections:
    """People found in one frame.

    ``boxes`` [M, 4] float32 xmin, ymin, xmax, ymax in the frame's pixels; ``scores`` [M] float32
    in 0..1, sorted descending; ``keypoints`` [M, 17, 3] (x, y, confidence, COCO-17 order, NaN where
    missing) or None when no keypoint model ran.
    """

    boxes: np.ndarray
    scores: np.ndarray
    keypoints: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @staticmethod
    def empty() -> Detections:
        return Detections(np.zeros((0, 4), np.float32), np.zeros((0,), np.float32))


class PersonDetector(ABC):
    """Finds people in a batch of BGR frames with one batched inference call."""

    kind: str = ""
    keypoints: bool = False  # whether :class:`Detections` carry keypoints (KeypointDetector)

    @abstractmethod
    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        """One :class:`Detections` per frame, in the same order, boxes in that frame's pixels."""

    def describe(self) -> str:
        """One line for logs and ``/v1/health``: type, model file, input geometry."""
        return self.kind


@runtime_checkable
class Resizable(Protocol):
    """An optional detector capability: a network that takes any input size (NanoDet) gives
    the same detector at another size (``models.detector.windows.WindowRefiner``). Checked
    once, when the daemon builds its detection stage."""

    def resized(self, input_size: tuple[int, int]) -> PersonDetector: ...


# The keypoint back-ends (models.detector.keypoints), named here so the settings can type them.
KeypointBackend = Literal["blazepose", "mediapipe"]


class DetectorSettingsBase(BaseModel):
    """Options every detector kind takes; a plugin's settings class adds its ``kind`` tag and own
    options (``models.detector.nanodet.NanoDetSettings``, ...)."""

    model_config = ConfigDict(extra="forbid")
    kind: str
    score_threshold: float = Field(
        0.4, ge=0.0, le=1.0, description="Boxes scoring below this are ignored."
    )
    threads: int = Field(2, ge=1, le=64, description="Inference threads.")
    keypoints: bool = Field(
        False,
        description="Add COCO-17 keypoints to every box (a pose network on each person's crop); "
        "required by a model trained with --observation keypoints.",
    )
    keypoint_backend: KeypointBackend = Field(
        "blazepose",
        description="The pose network for keypoints: blazepose (shipped ONNX, all crops of a "
        "frame set in one call) or mediapipe (MediaPipe Pose, needs momloc[keypoints]).",
    )

    def options(self, threads: int) -> dict[str, object]:
        """The detector's constructor options (unset optional ones left to the kind's default)."""
        options = self.model_dump(
            exclude={"kind", "keypoints", "keypoint_backend"}, exclude_none=True
        )
        options["threads"] = threads
        return options


_REGISTRY: dict[str, Callable[..., PersonDetector]] = {}
DEFAULT_DETECTOR = (
    "nanodet"  # chosen by bench/detector/accuracy.py (bench/results/detector_accuracy.md)
)


def register_detector(kind: str) -> Callable[[type[PersonDetector]], type[PersonDetector]]:
    """Class decorator adding a detector type to the registry under ``kind``."""

    def decorate(cls: type[PersonDetector]) -> type[PersonDetector]:
        cls.kind = kind
        _REGISTRY[kind] = cls
        return cls

    return decorate


def available_detectors() -> list[str]:
    _load_builtin_detectors()
    return sorted(_REGISTRY)


def create_detector(kind: str = DEFAULT_DETECTOR, **options: object) -> PersonDetector:
    """Build a detector by type name (``"nanodet"`` default, ``"ssdlite"``, ``"yolov8"``).

    ``options`` go to the detector's constructor (``model_path``, ``score_threshold``,
    ``letterbox``, ``threads``, ...). ``keypoints=True`` wraps it with a pose estimator
    (``keypoint_backend``: ``models.detector.keypoints``) so each :class:`Detections` carries
    COCO-17 keypoints.
    """
    _load_builtin_detectors()
    keypoints = bool(options.pop("keypoints", False))
    keypoint_backend = str(options.pop("keypoint_backend", "blazepose"))
    try:
        factory = _REGISTRY[kind]
    except KeyError:
        raise MomlocError(
            f"detector type {kind!r} is unknown (choose one of: {', '.join(sorted(_REGISTRY))})"
        ) from None
    try:
        inspect.signature(factory).bind(**options)
    except TypeError as error:
        raise MomlocError(f"detector {kind!r}: bad option ({error})") from None
    detector = factory(**options)
    if keypoints:
        from models.detector.keypoints import KeypointDetector, create_keypoint_estimator

        threads = options.get("threads")
        estimator = create_keypoint_estimator(
            keypoint_backend, threads=int(threads) if isinstance(threads, int) else None
        )
        detector = KeypointDetector(detector, estimator)
    return detector


def detector_from_settings(settings: DetectorSettingsBase, threads: int) -> PersonDetector:
    """The detector a validated settings object describes (``threads`` decided by the caller:
    the daemon runs one thread beside the pipeline unless threads was set)."""
    return create_detector(
        settings.kind,
        keypoints=settings.keypoints,
        keypoint_backend=settings.keypoint_backend,
        **settings.options(threads),
    )


def _load_builtin_detectors() -> None:
    # Imported here, not at module top, so base.py has no import cycle with its plugins.
    from models.detector import nanodet, ssdlite, yolov8  # noqa: F401


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def verify_shipped(path: Path) -> None:
    """Check a shipped model against the SHA-256 in ``<name>.sha256`` beside it, so a truncated
    clone or a Git LFS pointer fails at start with one clear line rather than with odd boxes."""
    checksum_file = path.with_name(path.name + ".sha256")
    if path.is_file() and file_sha256(path) != checksum_file.read_text().split()[0]:
        raise MomlocError(
            f"detector model {path}: checksum mismatch (damaged or a Git LFS pointer; "
            "reinstall momloc)"
        )


def warm_up(detector: PersonDetector, path: Path, frames: int) -> None:
    """Run the model once at load: allocations happen now, and a model that loads but cannot
    run (wrong shapes inside, unsupported op) fails at start with one line, not on frame one."""
    try:
        detector.detect([np.zeros((480, 640, 3), np.uint8)] * frames)
    except MomlocError:
        raise
    except Exception as error:
        lines = str(error).strip().splitlines() or [type(error).__name__]
        raise MomlocError(f"detector model {path}: fails on a test frame ({lines[0]})") from None
