"""Real-photograph checks for person detectors, built from scikit-image's bundled photographs.

Why: synthetic renders say little about a detector trained on real people, and nothing may be
downloaded. scikit-image (a dev/test dependency, imported lazily) ships a few photographs inside
its wheel: two with a person (``astronaut``, ``camera``) and several without. We paste them,
scaled, into 640×480 frames so the person is a known number of pixels tall at a known place, which
gives recall against person height and a box to compare with (IoU).

The person extents below were annotated by hand on the 512×512 originals (the whole visible body,
without held objects; both photos are cut off at the bottom edge, so the "height" is the visible
extent).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from models.detector.base import PersonDetector
from models.detector.preprocessing import box_iou

FRAME_SIZE = (640, 480)
PERSON_EXTENTS = {  # xmin, ymin, xmax, ymax in the original photograph
    "astronaut": (18.0, 14.0, 365.0, 512.0),
    "camera": (0.0, 62.0, 330.0, 512.0),
}
NO_PEOPLE = ("chelsea", "coffee", "rocket", "horse", "coins", "moon", "hubble_deep_field")


def photo(name: str) -> np.ndarray:
    """A scikit-image photograph as uint8 BGR [H, W, 3] (grey and binary images expanded)."""
    from skimage import data

    image = np.asarray(getattr(data, name)())
    if image.dtype == bool:
        image = image.astype(np.uint8) * 255
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return cv2.cvtColor(image[..., :3], cv2.COLOR_RGB2BGR)


def background(seed: int = 0) -> np.ndarray:
    """A plain, slightly noisy grey 640×480 frame: no texture for the detector to latch onto."""
    rng = np.random.default_rng(seed)
    frame = rng.normal(128, 6, (FRAME_SIZE[1], FRAME_SIZE[0], 3))
    return frame.clip(0, 255).astype(np.uint8)


def paste(
    image: np.ndarray, frame: np.ndarray, scale: float, anchor: tuple[float, float]
) -> tuple[np.ndarray, tuple[float, float]]:
    """Paste ``image`` scaled by ``scale`` into a copy of ``frame``; ``anchor`` (0..1, 0..1) puts
    the pasted patch's top-left corner at that fraction of the free room. Returns the frame and
    the patch's top-left pixel. Patches larger than the frame are cropped at the frame border."""
    height, width = frame.shape[:2]
    scaled = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    ph, pw = scaled.shape[:2]
    x0 = round(max(width - pw, 0) * anchor[0])
    y0 = round(max(height - ph, 0) * anchor[1])
    out = frame.copy()
    visible = scaled[: height - y0, : width - x0]
    out[y0 : y0 + visible.shape[0], x0 : x0 + visible.shape[1]] = visible
    return out, (float(x0), float(y0))


def person_frame(
    name: str, person_height: float, anchor: tuple[float, float] = (0.5, 1.0), seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """A 640×480 frame with photo ``name`` scaled so its person is ``person_height`` px tall;
    returns the frame and the person's true box [4] in frame pixels (clipped to the frame)."""
    extent = np.array(PERSON_EXTENTS[name])
    scale = person_height / (extent[3] - extent[1])
    frame, (x0, y0) = paste(photo(name), background(seed), scale, anchor)
    box = extent * scale + np.array([x0, y0, x0, y0])
    box[[0, 2]] = box[[0, 2]].clip(0, FRAME_SIZE[0])
    box[[1, 3]] = box[[1, 3]].clip(0, FRAME_SIZE[1])
    return frame, box.astype(np.float32)


@dataclass(frozen=True)
class RecallRow:
    person_height: int
    trials: int
    found: int
    mean_iou: float

    @property
    def recall(self) -> float:
        return self.found / self.trials if self.trials else float("nan")


def recall_by_height(
    detector: PersonDetector,
    heights: Sequence[int],
    anchors: Sequence[tuple[float, float]] = ((0.0, 1.0), (0.5, 0.5), (1.0, 1.0)),
    iou_threshold: float = 0.5,
) -> list[RecallRow]:
    """Recall (a detection with IoU ≥ ``iou_threshold`` with the true box) per person height,
    over both people photographs and several positions, frames batched in pairs as in serving."""
    rows = []
    for height in heights:
        cases = [person_frame(n, height, a) for n in PERSON_EXTENTS for a in anchors]
        ious = []
        for start in range(0, len(cases), 2):
            pair = cases[start : start + 2]
            for (_, truth), found in zip(pair, detector.detect([f for f, _ in pair]), strict=True):
                best = box_iou(truth, found.boxes).max() if len(found) else 0.0
                ious.append(float(best))
        hits = [iou for iou in ious if iou >= iou_threshold]
        rows.append(
            RecallRow(height, len(ious), len(hits), float(np.mean(hits)) if hits else float("nan"))
        )
    return rows
