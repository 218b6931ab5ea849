"""Which box is the person on a mark: the still-person rule of floor-mark recording.

Why: the per-frame filter (:func:`service.setup.collector.frame_row`) keeps a frame when no camera
shows more than one box. When a camera misses the person and a false box (a coat, a plant, a
door frame) is the only box there, that false box was recorded as the person at the mark. With
the measured ``nanodet`` profile on the synthetic room this made the set-up models poor (3 × 3
marks: validation error 0.88-1.48 m, check 0.65-1.45 m; 2026-12-01), and offline ``momloc eval``
rows kept the same false boxes, so the live check and ``momloc eval`` disagreed.

The rule: a person standing on a mark is still (swaying and turning in place), so over the frames
of one mark each camera sees them at one place and one size. Per camera, the robust position of
the person is the median over the mark's boxes of the foot point (bottom-centre) and the box
height; a box whose foot is far from that median, or whose height differs from it by a large
factor, is not the person and is dropped (the camera counts as not seeing anyone in that frame).
Distances are in units of the median box height, so the rule holds at any resolution and
distance. The tolerance per quantity is 4 robust standard deviations (1.4826 · MAD) of the mark's
own boxes, clipped to ``[FLOOR, CAP]``: a noisier detector gets a wider band (the measured
``nanodet`` bottom-edge noise is 0.10 box heights), never so wide that anything passes, and a
noise-free detector never drops a person for a pixel of sway. Boxes of one mark are judged
together at the end of its record step (:func:`keep_mask`); judging each frame against a running
median was rejected: the first frames of a mark would be judged on a handful of boxes.

What it cannot do: when false boxes are most of one camera's boxes at a mark (the person is out
of that camera's view and one spot fires in most frames), the median is the false box: one mark
alone cannot tell. Across marks it can (a box place one camera repeats at marks far apart, or a
mark off the floor map the others agree on), which the floor-map fit does
(:mod:`models.mark_fit`); the per-mark quality shows the camera's count, and the check step
shows a poor mark.
"""

from __future__ import annotations

import numpy as np

MAD_SIGMAS = 4.0  # deviations beyond 4 robust sigmas are not the person
MAD_TO_SIGMA = 1.4826
# Bands in box heights (foot) and in log height ratio: (floor, cap).
FOOT_BAND = (0.2, 0.6)  # a sway of 0.15 m is ~0.1 person heights; a stride away is > 0.6
LOG_HEIGHT_BAND = (float(np.log(1.2)), float(np.log(1.6)))


def keep_mask(boxes: np.ndarray) -> np.ndarray:
    """Per row and camera, whether the box is the still person: ``boxes`` [N, K, 4] (x1, y1,
    x2, y2; NaN = no box) of one mark → bool [N, K] (False where there is no box)."""
    boxes = np.asarray(boxes, float)
    seen = np.isfinite(boxes).all(axis=2)
    keep = np.zeros(seen.shape, bool)
    for k in range(boxes.shape[1]):
        rows = np.flatnonzero(seen[:, k])
        if rows.size:
            keep[rows, k] = _consistent(boxes[rows, k])
    return keep


def _consistent(boxes: np.ndarray) -> np.ndarray:
    """Which of one camera's boxes [M, 4] agree with their median foot point and height."""
    height = np.maximum(boxes[:, 3] - boxes[:, 1], 1e-6)
    foot = np.stack([(boxes[:, 0] + boxes[:, 2]) / 2, boxes[:, 3]], axis=1)
    scale = float(np.median(height))
    du, dv = ((foot - np.median(foot, axis=0)) / scale).T
    dh = np.log(height / scale)
    return (
        (np.abs(du) <= _band(du, FOOT_BAND))
        & (np.abs(dv) <= _band(dv, FOOT_BAND))
        & (np.abs(dh) <= _band(dh, LOG_HEIGHT_BAND))
    )


def _band(deviation: np.ndarray, limits: tuple[float, float]) -> float:
    """The tolerance for deviations from the median: 4 robust sigmas, clipped to ``limits``."""
    mad = float(np.median(np.abs(deviation - np.median(deviation))))
    return float(np.clip(MAD_SIGMAS * MAD_TO_SIGMA * mad, *limits))
