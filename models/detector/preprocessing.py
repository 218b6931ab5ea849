"""Frame → network input, and network boxes → original frame pixels.

Two geometries, chosen per detector (``letterbox=`` option):

- **plain resize**: the frame is stretched to the network's square input. A 640×480 frame
  into 300×300 shrinks x by 0.47 and y by 0.625, so a standing person keeps *more* height in
  pixels than with letterboxing but becomes thinner than in training images.
- **letterbox**: scale to fit, keep the aspect ratio, pad the rest with grey (114, as YOLO does).
  Undistorted people, but everything is smaller (0.47 in both directions for 640×480 → 300).

Which one finds more small people is measured, not assumed: ``bench/detector/speed.py`` reports
recall against person height for both, and each detector's default follows that measurement.

Every transform is described by a :class:`Geometry` (scale and padding per frame), so mapping back
is one affine step and boxes always come back in the caller's original pixels.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from common.errors import MomlocError

PAD_VALUE = 114


@dataclass(frozen=True)
class Geometry:
    """How one frame was mapped into the network input: ``net = frame * scale + pad``."""

    scale_x: float
    scale_y: float
    pad_x: float
    pad_y: float
    width: int  # original frame size, for clipping
    height: int

    def to_frame(self, boxes_net: np.ndarray) -> np.ndarray:
        """Boxes [M, 4] xmin, ymin, xmax, ymax in network pixels → clipped frame pixels."""
        boxes = np.asarray(boxes_net, np.float32).reshape(-1, 4).copy()
        boxes[:, [0, 2]] = (boxes[:, [0, 2]] - self.pad_x) / self.scale_x
        boxes[:, [1, 3]] = (boxes[:, [1, 3]] - self.pad_y) / self.scale_y
        boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, self.width)
        boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, self.height)
        return boxes


def input_side(base: int, side: int, max_shrink: float | None, step: int = 32) -> int:
    """One side of the network input for a frame side of ``side`` pixels: ``base`` while the
    frame shrinks into it by at most ``max_shrink``, otherwise the side shrunk by ``max_shrink``
    and rounded up to a multiple of ``step`` (``base`` itself is one). ``None``: ``base``."""
    if max_shrink is None:
        return base
    return max(base, math.ceil(side / max_shrink / step) * step)


def input_for_frame(
    base: tuple[int, int], frame_size: tuple[int, int], max_shrink: float | None, step: int = 32
) -> tuple[int, int]:
    """The network input (width, height) for a frame of ``frame_size``, side by side by
    :func:`input_side`: ``base`` for a 640×480 webcam frame into 320×256 at ``max_shrink`` 3,
    640×384 for a 1920×1080 frame.

    Why grow with the frame: a fixed input throws a large frame's resolution away. A person
    130 px tall in a 1920×1080 frame is 31 px tall (and, squeezed 6× across but 4.2× down,
    thinner than any person the network was trained on) in a 320×256 input, where the detector
    misses most people. Each side grows on its own, so the input keeps the frame's aspect ratio
    once both sides grow.
    """
    return (
        input_side(base[0], frame_size[0], max_shrink, step),
        input_side(base[1], frame_size[1], max_shrink, step),
    )


def check_frame(frame: np.ndarray, index: int) -> None:
    if not isinstance(frame, np.ndarray) or frame.ndim != 3 or frame.shape[2] != 3:
        shape = getattr(frame, "shape", type(frame).__name__)
        raise MomlocError(f"frame {index}: expected a BGR image [H, W, 3], got {shape}")
    if frame.dtype != np.uint8:
        raise MomlocError(f"frame {index}: expected uint8 pixels, got {frame.dtype}")


def fit_frame(
    frame: np.ndarray, size: tuple[int, int], letterbox: bool, rgb: bool = True
) -> tuple[np.ndarray, Geometry]:
    """Resize a BGR frame to ``size`` (width, height) of the network; return it (RGB unless
    ``rgb`` is False, for networks trained on BGR) and its geometry."""
    height, width = frame.shape[:2]
    net_w, net_h = size
    if letterbox:
        scale = min(net_w / width, net_h / height)
        new_w, new_h = max(1, round(width * scale)), max(1, round(height * scale))
        pad_x, pad_y = (net_w - new_w) // 2, (net_h - new_h) // 2
        padded = np.full((net_h, net_w, 3), PAD_VALUE, np.uint8)
        resized = cv2.resize(frame, (new_w, new_h), interpolation=_interpolation(scale))
        padded[pad_y : pad_y + new_h, pad_x : pad_x + new_w] = resized
        canvas: np.ndarray = padded
        geometry = Geometry(new_w / width, new_h / height, pad_x, pad_y, width, height)
    else:
        scale_x, scale_y = net_w / width, net_h / height
        if (net_w, net_h) == (width, height):
            canvas = frame
        else:
            canvas = cv2.resize(frame, (net_w, net_h), interpolation=_interpolation(scale_x))
        geometry = Geometry(scale_x, scale_y, 0.0, 0.0, width, height)
    return (cv2.cvtColor(canvas, cv2.COLOR_BGR2RGB) if rgb else canvas), geometry


def make_batch(
    frames: Sequence[np.ndarray], size: tuple[int, int], letterbox: bool, rgb: bool = True
) -> tuple[np.ndarray, list[Geometry]]:
    """Stack frames of any sizes into one uint8 batch [N, H, W, 3] (RGB unless ``rgb`` is
    False) for a single call."""
    batch = np.empty((len(frames), size[1], size[0], 3), np.uint8)
    geometries = []
    for index, frame in enumerate(frames):
        check_frame(frame, index)
        batch[index], geometry = fit_frame(frame, size, letterbox, rgb)
        geometries.append(geometry)
    return batch, geometries


def _interpolation(scale: float) -> int:
    # INTER_AREA when shrinking avoids aliasing that erases thin limbs; LINEAR when enlarging.
    return cv2.INTER_AREA if scale < 1.0 else cv2.INTER_LINEAR


def nms(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Greedy non-maximum suppression; indices of kept boxes, highest score first."""
    order = np.argsort(-scores, kind="stable")
    boxes = np.asarray(boxes, np.float32)
    areas = np.maximum(boxes[:, 2] - boxes[:, 0], 0) * np.maximum(boxes[:, 3] - boxes[:, 1], 0)
    keep: list[int] = []
    while order.size:
        best, rest = order[0], order[1:]
        keep.append(int(best))
        ix0 = np.maximum(boxes[best, 0], boxes[rest, 0])
        iy0 = np.maximum(boxes[best, 1], boxes[rest, 1])
        ix1 = np.minimum(boxes[best, 2], boxes[rest, 2])
        iy1 = np.minimum(boxes[best, 3], boxes[rest, 3])
        inter = np.maximum(ix1 - ix0, 0) * np.maximum(iy1 - iy0, 0)
        iou = inter / np.maximum(areas[best] + areas[rest] - inter, 1e-9)
        order = rest[iou <= iou_threshold]
    return np.asarray(keep, np.int64)


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU matrix [len(a), len(b)] of xmin, ymin, xmax, ymax boxes."""
    a = np.asarray(a, np.float64).reshape(-1, 1, 4)
    b = np.asarray(b, np.float64).reshape(1, -1, 4)
    ix = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0, None)
    iy = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0, None)
    inter = ix * iy
    area_a = (a[..., 2] - a[..., 0]) * (a[..., 3] - a[..., 1])
    area_b = (b[..., 2] - b[..., 0]) * (b[..., 3] - b[..., 1])
    return inter / np.maximum(area_a + area_b - inter, 1e-12)
