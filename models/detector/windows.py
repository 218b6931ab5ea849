"""Second look at small people: re-detect them in windows around known boxes, at a higher scale.

Why: the full-frame pass shrinks a 640×480 frame to the network's 320×256, so a person 80 px
tall becomes 43 px, where NanoDet's recall falls and its bottom edge (the foot, which carries a
single-view floor position) is least precise. Running the whole frame at a larger input costs
CPU in proportion to the pixels (0.37 CPU-µs per input pixel on the 2-core host, measured), most
of them empty floor and wall. A window around a person already known (found in an earlier frame
set, carried by the image-space tracker) costs a small fixed input and sees that person at
~``target_height`` px, where the detector is at its best.

Each window is ``context`` × the box height tall (room for the box to have moved, and for the
network to see the person whole), with the aspect of the window detector's input, centred on the
box and shifted (not shrunk) to stay inside the frame; windows of all frames go into one batched
call. From each window the box closest to the prior (IoU, ≥ ``min_iou``) replaces the prior's
full-frame match; a window that finds nobody drops nothing (the full-frame result stands).

Example::

    refine = WindowRefiner(create_detector("nanodet"))
    detections = refine(frames, full_frame_detections, priors)  # priors: [M_k, 4] per frame
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from models.detector.base import Detections, PersonDetector
from models.detector.preprocessing import box_iou


@dataclass(frozen=True)
class Window:
    """One crop: which frame, where (x0, y0, x1, y1 in frame pixels), and the prior box."""

    frame: int
    rect: tuple[int, int, int, int]
    prior: np.ndarray


def plan_windows(
    priors: Sequence[np.ndarray],
    frame_sizes: Sequence[tuple[int, int]],
    aspect: float,
    context: float,
    max_height: float,
    min_window: int = 48,
) -> list[Window]:
    """Windows around every prior box shorter than ``max_height`` px.

    ``aspect`` is the window's width / height (the window detector's input aspect); windows are
    at least ``min_window`` px tall and never larger than the frame."""
    windows = []
    for index, (boxes, (width, height)) in enumerate(zip(priors, frame_sizes, strict=True)):
        for box in np.asarray(boxes, np.float32).reshape(-1, 4):
            box_height = float(box[3] - box[1])
            if not np.isfinite(box).all() or box_height <= 0 or box_height >= max_height:
                continue
            win_h = min(max(box_height * context, min_window), height)
            win_w = min(win_h * aspect, width)
            cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
            x0 = round(float(np.clip(cx - win_w / 2, 0, width - win_w)))
            y0 = round(float(np.clip(cy - win_h / 2, 0, height - win_h)))
            rect = (x0, y0, x0 + round(win_w), y0 + round(win_h))
            windows.append(Window(index, rect, box))
    return windows


class WindowRefiner:
    """Re-detects known small people in windows, one batched call for all windows of all frames.

    Parameters
    ----------
    detector: the window detector; its own input size sets the window's scale (NanoDet at
        128×192 sees a window of 1.6 × box height at 120 px per person).
    context: window height / prior box height.
    max_height: priors at least this tall (frame px) are left to the full-frame pass.
    min_iou: a window's box must overlap its prior this much to replace the full-frame match.
    max_windows: at most this many windows per call (the smallest priors first), so the cost
        is bounded whatever the scene.
    """

    def __init__(
        self,
        detector: PersonDetector,
        context: float = 1.6,
        max_height: float = 120.0,
        min_iou: float = 0.3,
        max_windows: int = 4,
    ) -> None:
        self.detector = detector
        size = getattr(detector, "input_size", (128, 192))
        self.aspect = float(size[0]) / float(size[1])
        self.context = float(context)
        self.max_height = float(max_height)
        self.min_iou = float(min_iou)
        self.max_windows = int(max_windows)

    def __call__(
        self,
        frames: Sequence[np.ndarray],
        detections: Sequence[Detections],
        priors: Sequence[np.ndarray],
    ) -> list[Detections]:
        sizes = [(frame.shape[1], frame.shape[0]) for frame in frames]
        windows = plan_windows(priors, sizes, self.aspect, self.context, self.max_height)
        windows = sorted(windows, key=lambda w: float(w.prior[3] - w.prior[1]))
        windows = windows[: self.max_windows]
        if not windows:
            return list(detections)
        crops = [frames[w.frame][w.rect[1] : w.rect[3], w.rect[0] : w.rect[2]] for w in windows]
        found = self.detector.detect(crops)
        merged = [(d.boxes.copy(), d.scores.copy()) for d in detections]
        for window, result in zip(windows, found, strict=True):
            if len(result) == 0:
                continue
            offset = np.array(window.rect[:2] * 2, np.float32)
            boxes = result.boxes + offset
            overlap = box_iou(window.prior, boxes)[0]
            best = int(np.argmax(overlap))
            if overlap[best] < self.min_iou:
                continue
            merged[window.frame] = _replace(*merged[window.frame], boxes[best], result.scores[best])
        return [_sorted(boxes, scores) for boxes, scores in merged]


def _replace(
    boxes: np.ndarray, scores: np.ndarray, box: np.ndarray, score: float
) -> tuple[np.ndarray, np.ndarray]:
    """Put ``box`` in place of the full-frame boxes it overlaps (IoU ≥ 0.3), or add it."""
    if len(boxes):
        same = box_iou(box, boxes)[0] >= 0.3
        boxes, scores = boxes[~same], scores[~same]
    return (
        np.vstack([boxes, box[None]]).astype(np.float32),
        np.append(scores, np.float32(score)).astype(np.float32),
    )


def _sorted(boxes: np.ndarray, scores: np.ndarray) -> Detections:
    order = np.argsort(-scores, kind="stable")
    return Detections(boxes[order].reshape(-1, 4), scores[order])
