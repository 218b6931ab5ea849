"""Test doubles for association: a tiny calibrated scene and an "oracle" MoM runtime.

The oracle implements the ``MomRuntime`` methods association uses from true projection matrices:
``reproject`` projects the body's mid-height point, which is what the MoM decoder learns to predict
(the box centre, ``models.mom.sampling.unit_mean``); ``localize`` is its least-squares inverse over
the seen box centres (exact for one view, a compromise for an inconsistent tuple).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from models.geometry.floor_prior import FloorPrior
from service.stages import WorldBounds

MID_HEIGHT = 0.85
PERSON_HEIGHT = 1.7
PERSON_HALF_WIDTH = 0.25


def look_at(position: np.ndarray, target: np.ndarray, focal: float = 500.0) -> np.ndarray:
    """3×4 projection of a 640×480 pinhole camera at ``position`` looking at ``target``."""
    forward = target - position
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right = right / np.linalg.norm(right)
    down = np.cross(forward, right)
    rotation = np.stack([right, down, forward])
    k = np.array([[focal, 0, 320.0], [0, focal, 240.0], [0, 0, 1]])
    return k @ np.hstack([rotation, -(rotation @ position)[:, None]])


def room_cameras(count: int) -> np.ndarray:
    """``count`` cameras (≤ 4) in the corners of a 6 × 6 m room, 2.4 m high, facing the centre."""
    corners = [(-0.5, -0.5), (6.5, -0.5), (6.5, 6.5), (-0.5, 6.5)]
    centre = np.array([3.0, 3.0, 0.8])
    return np.stack([look_at(np.array([x, y, 2.4]), centre) for x, y in corners[:count]])


def project(p: np.ndarray, points: np.ndarray) -> np.ndarray:
    homogeneous = np.concatenate([points, np.ones((*points.shape[:-1], 1))], axis=-1)
    q = homogeneous @ p.T
    return q[..., :2] / q[..., 2:]


def person_boxes(projections: np.ndarray, world: np.ndarray) -> np.ndarray:
    """Boxes [P, K, 4] of upright cylinders (as 16 rim points) standing at ``world`` [P, 2]."""
    angles = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    rim = np.stack([np.cos(angles), np.sin(angles)], axis=1) * PERSON_HALF_WIDTH
    out = np.zeros((len(world), len(projections), 4))
    for i, (x, y) in enumerate(world):
        pts = np.concatenate(
            [
                np.column_stack([x + rim[:, 0], y + rim[:, 1], np.full(8, z)])
                for z in (0.0, PERSON_HEIGHT)
            ]
        )
        for k, p in enumerate(projections):
            px = project(p, pts)
            out[i, k] = [*px.min(axis=0), *px.max(axis=0)]
    return out


class ModelDouble:
    """The part of :class:`~service.stages.LocalizationModel` a localizer double does not model,
    answered the way ``MomRuntime`` answers for a model file without it: no fitted floor prior
    (covariance NaN, no floor views), no set-up area (everyone inside), no stored bounds, and a
    decoder that puts nobody in any image (NaN pixels: no line of sight, no camera covers
    anyone), no directory or ``model.json``. A double sets ``num_cameras`` and ``image_sizes``
    and defines ``localize`` and ``reprojection_error``; one with geometry overrides
    ``reproject``."""

    num_cameras: int
    image_sizes: np.ndarray
    observation = "bbox"
    world_bounds: WorldBounds | None = None
    model_dir = Path("model-double")  # no directory: nothing reads it
    meta: dict[str, Any] = {}  # noqa: RUF012 (never mutated)
    floor_prior: FloorPrior | None = None

    def reproject(self, world: np.ndarray) -> np.ndarray:
        return np.full((len(np.asarray(world).reshape(-1, 2)), self.num_cameras, 2), np.nan)

    def covariance(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        return np.full((len(boxes), 2, 2), np.nan)

    def floor_views(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray] | None:
        return None

    def inside(self, boxes: np.ndarray, world: np.ndarray) -> np.ndarray:
        return np.ones(len(boxes), dtype=bool)


class OracleRuntime(ModelDouble):
    """``MomRuntime`` stand-in built from true projection matrices (see the module docstring)."""

    def __init__(self, projections: np.ndarray) -> None:
        self.projections = np.asarray(projections, dtype=np.float64)
        self.num_cameras = len(self.projections)
        self.image_sizes = np.tile([640, 480], (self.num_cameras, 1))

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        """Least-squares floor point whose mid-height point projects onto the seen box centres."""
        boxes = np.asarray(boxes, dtype=np.float64)
        centre = (boxes[..., :2] + boxes[..., 2:]) / 2
        out = np.full((len(boxes), 2), np.nan)
        for b in range(len(boxes)):
            rows, rhs = [], []
            for k, p in enumerate(self.projections):
                if not np.isfinite(centre[b, k]).all():
                    continue
                for axis in (0, 1):  # u * (p3 . X) - p_axis . X = 0 with X = (x, y, z0, 1)
                    row = centre[b, k, axis] * p[2] - p[axis]
                    rows.append(row[:2])
                    rhs.append(-(row[2] * MID_HEIGHT + row[3]))
            if rows:
                out[b] = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0]
        return out

    def reproject(self, world: np.ndarray) -> np.ndarray:
        world = np.asarray(world, dtype=np.float64)
        points = np.concatenate([world, np.full((len(world), 1), MID_HEIGHT)], axis=1)
        return np.stack([project(p, points) for p in self.projections], axis=1)

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        centre = (np.asarray(boxes)[..., :2] + np.asarray(boxes)[..., 2:]) / 2
        return np.linalg.norm(self.reproject(world) - centre, axis=-1)
