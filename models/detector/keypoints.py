"""Optional 2D keypoints (COCO-17) on detector crops: the shared parts and the back-ends' choice.

Two back-ends compute the same thing, ``[M, 17, 3]`` x, y (frame pixels) and confidence per
person box, NaN rows where no pose was found (never a guess):

- ``blazepose`` (default, :mod:`models.detector.keypoints_blazepose`): BlazePose Lite's landmark
  network as shipped ONNX, every crop of a frame set in one call (OpenVINO where installed, else
  onnxruntime); no extra install.
- ``mediapipe`` (:mod:`models.detector.keypoints_mediapipe`): MediaPipe Pose
  (``momloc[keypoints]``), one call per crop, the reference the default was measured against.

Why BlazePose Lite is the default: ``bench/results/keypoint_speed.md`` (CPU per frame set of
3 people × 2 cameras and agreement with MediaPipe on the same crops). Both name their joints as
MediaPipe's 33 landmarks, mapped to COCO-17 by name (:data:`MEDIAPIPE_TO_COCO`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from common.errors import MomlocError
from models.detector.base import Detections, KeypointBackend, PersonDetector

COCO_NAMES = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
)  # fmt: skip
# MediaPipe Pose landmark index for each COCO-17 joint, in COCO order.
MEDIAPIPE_TO_COCO = np.array([0, 2, 5, 7, 8, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28])
MEDIAPIPE_LANDMARKS = 33


def landmarks_to_coco(landmarks: np.ndarray, box: Sequence[float]) -> np.ndarray:
    """[33, 3] MediaPipe (x, y normalised to the crop, visibility) → [17, 3] COCO in frame pixels.

    ``box`` is the crop's xmin, ymin, xmax, ymax in frame pixels.
    """
    landmarks = np.asarray(landmarks, np.float32)
    if landmarks.shape != (MEDIAPIPE_LANDMARKS, 3):
        raise ValueError(f"expected [33, 3] landmarks, got {landmarks.shape}")
    x0, y0, x1, y1 = (float(v) for v in box)
    coco = landmarks[MEDIAPIPE_TO_COCO].copy()
    coco[:, 0] = x0 + coco[:, 0] * (x1 - x0)
    coco[:, 1] = y0 + coco[:, 1] * (y1 - y0)
    return coco


def crop_box(
    box: Sequence[float] | np.ndarray, width: int, height: int, margin: float
) -> np.ndarray:
    """The detector box widened by ``margin`` of its size on each side, in whole pixels, clipped."""
    x0, y0, x1, y1 = (float(v) for v in box)
    dx, dy = (x1 - x0) * margin, (y1 - y0) * margin
    return np.array(
        [
            max(0, int(np.floor(x0 - dx))),
            max(0, int(np.floor(y0 - dy))),
            min(width, int(np.ceil(x1 + dx))),
            min(height, int(np.ceil(y1 + dy))),
        ],
        np.int64,
    )


class KeypointEstimator(Protocol):
    """What a keypoint back-end offers (both compute the same thing: see the module)."""

    def describe(self) -> str: ...

    def estimate(self, frame: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """[M, 17, 3] for the boxes [M, 4] of one BGR frame."""
        ...

    def estimate_frames(
        self, frames: list[np.ndarray], boxes: list[np.ndarray]
    ) -> list[np.ndarray]:
        """:meth:`estimate` for every frame of a frame set (batched where the back-end can)."""
        ...

    def close(self) -> None: ...


KEYPOINT_BACKENDS: tuple[KeypointBackend, ...] = ("blazepose", "mediapipe")
DEFAULT_KEYPOINT_BACKEND: KeypointBackend = "blazepose"


def create_keypoint_estimator(
    backend: str = DEFAULT_KEYPOINT_BACKEND, threads: int | None = None
) -> KeypointEstimator:
    """The keypoint back-end named ``backend`` (imported only when chosen: MediaPipe is optional).

    ``threads`` sets the ONNX back-end's inference threads (MediaPipe chooses its own)."""
    if backend == "blazepose":
        from models.detector.keypoints_blazepose import BlazePoseLite

        return BlazePoseLite(threads=threads)
    if backend == "mediapipe":
        from models.detector.keypoints_mediapipe import MediaPipePose

        return MediaPipePose()
    raise MomlocError(
        f"keypoint back-end {backend!r} is unknown (choose one of: {', '.join(KEYPOINT_BACKENDS)})"
    )


class KeypointDetector(PersonDetector):
    """Wraps any person detector and adds COCO-17 keypoints to its detections."""

    keypoints = True

    def __init__(self, detector: PersonDetector, estimator: KeypointEstimator | None = None):
        self.detector = detector
        self.estimator = estimator or create_keypoint_estimator()
        self.kind = detector.kind

    def describe(self) -> str:
        return f"{self.detector.describe()} + {self.estimator.describe()}"

    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        results = self.detector.detect(frames)
        keypoints = self.estimator.estimate_frames(list(frames), [found.boxes for found in results])
        return [
            Detections(found.boxes, found.scores, points)
            for found, points in zip(results, keypoints, strict=True)
        ]
