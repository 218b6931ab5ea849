"""A camera's image transform: how a bumped camera's image relates to the one its model learned.

Why: a camera knocked by a few degrees (rolled about its optical axis, panned or tilted a
little) sees the same room through one image homography ``H`` (exact for a pure rotation of the
camera, and its translation in a room is millimetres). Its boxes then say, through ``H^-1``,
where the person would have been in the image the model was set up on, and the model's encoder,
floor maps and decoder still hold there. So a repair (:mod:`service.learning.heal`) can estimate
eight numbers (four for a similarity) instead of refitting the maps, and the runtime serves the
former model with each camera's boxes mapped back first (``model.json`` ``image_transforms``,
:class:`~models.mom.runtime.MomRuntime`).

Boxes are not points: a rolled camera's box is the axis-aligned bounding box of a rotated
person, so its corners are not the rotated corners. The box centre maps as a point (a body is
about symmetric about its centre); the size is un-boxed through the local linear part ``J`` of
``H`` at the centre: a person of width ``w`` and height ``h`` spans ``w' = |J00| w +
WIDTH_FROM_HEIGHT |J01| h`` and ``h' = |J11| h``. A rectangle would take the whole of the other
side (1 and 1); a person's extremes are narrow (head, feet) and the width is the arms' and
legs' swing, so rolling the image widens a person's box by 0.17 h sin(roll) and leaves its
height as it was (indoor-2cam, ideal boxes of the simulator's bodies, roll 3°: fitted 0.17 and
-0.3 ± noise; taking the rectangle's 1 for the height moved the box bottoms by 1 px more).

Convention: ``H`` [3, 3] maps the model's (pre-bump) image to the camera's current image;
``None`` (``null`` in JSON) is the identity.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

WIDTH_FROM_HEIGHT = 0.2


def apply(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Pixels [..., 2] mapped by homography ``h``; NaN stays NaN."""
    points = np.asarray(points, dtype=np.float64)
    homogeneous = points @ h[:, :2].T + h[:, 2]
    w = homogeneous[..., 2:]
    return homogeneous[..., :2] / np.where(np.abs(w) < 1e-12, 1e-12, w)


def jacobian(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The local linear part [..., 2, 2] of homography ``h`` at pixels [..., 2]."""
    points = np.asarray(points, dtype=np.float64)
    w = points @ h[2, :2] + h[2, 2]
    mapped = apply(h, points)
    return (h[:2, :2] - mapped[..., :, None] * h[2, :2]) / w[..., None, None]


def boxes_to_model(h: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Current-image boxes [..., 4] (x1, y1, x2, y2) → the boxes in the model's image (module
    docstring: the centre mapped by ``h^-1``, the size un-boxed through ``h``'s linear part)."""
    boxes = np.asarray(boxes, dtype=np.float64)
    inverse = np.linalg.inv(h)
    centre = apply(inverse, (boxes[..., :2] + boxes[..., 2:]) / 2)
    size = boxes[..., 2:] - boxes[..., :2]
    j = np.abs(jacobian(h, np.nan_to_num(centre)))
    height = size[..., 1] / np.maximum(j[..., 1, 1], 1e-6)
    width = (size[..., 0] - WIDTH_FROM_HEIGHT * j[..., 0, 1] * height) / np.maximum(
        j[..., 0, 0], 1e-6
    )
    wh = np.stack([width, height], axis=-1)
    wh = np.maximum(wh, 0.05 * size)  # a degenerate transform must not turn boxes inside out
    return np.concatenate([centre - wh / 2, centre + wh / 2], axis=-1)


def keypoints_to_model(h: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """Current-image keypoints [..., J, 3] (x, y, confidence) → the model's image."""
    keypoints = np.asarray(keypoints, dtype=np.float64)
    moved = apply(np.linalg.inv(h), keypoints[..., :2])
    return np.concatenate([moved, keypoints[..., 2:]], axis=-1)


def from_json(
    entries: Sequence[Sequence[Sequence[float]] | None] | None, cameras: int
) -> list[np.ndarray | None]:
    """``model.json`` ``image_transforms`` (one 3 × 3 or null per camera; absent: none)."""
    if entries is None:
        return [None] * cameras
    return [None if e is None else np.asarray(e, dtype=np.float64) for e in entries]
