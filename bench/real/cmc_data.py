"""The CMC room (Ong, Vo, Vo, Kim, Nordholm, TPAMI 2020) read from ``../shared/data/cmc``.

Evaluation only: nothing here is copied into the repository; the bench reads the files from the
path it is given. What this module knows about the data set (``cmc/SOURCE.txt``):

- 4 cameras, 1920 x 1024, 4 fps; sequence codes CMC1 = ``J_1_1``, CMC2 = ``J_5_2``.
- Truth rows ``frame id -1 -1 -1 -1 -1 x_c y_c z_c [..]``: the floor position is (x_c, y_c), the
  person's ellipsoid centre height z_c is half the body height (so the head is at ~2 z_c).
- The authors' tracking area x in [2.03, 6.3], y in [0, 3.41] m: the scored region.

The **evaluation pairing** (:func:`pair_boxes`) decides which real box belongs to which person,
using the projection matrices: this is the only place calibration enters, to make labels and to
attribute errors, never to serve. Each person's expected box is the image of a vertical segment
from the floor point to the head point (z = 2 z_c), widened to 0.4 x its height and clipped to
the image; boxes and people are matched by the Hungarian algorithm on 1 - IoU, pairs with IoU
below :data:`MIN_IOU` never (a box mostly hidden by another person or truncated to a fragment
stays unpaired: a loose but honest pairing).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from common.errors import MomlocError

SEQUENCES = {"CMC1": "J_1_1", "CMC2": "J_5_2"}
IMAGE_SIZE = (1920, 1024)
FPS = 4.0
NUM_CAMERAS = 4
AREA = ((2.03, 6.3), (0.0, 3.41))  # x, y ranges (m) of the authors' tracking area
MIN_IOU = 0.3
WIDTH_RATIO = 0.4  # expected box width over height, for the pairing only


@dataclass(frozen=True)
class Truth:
    """Per-row frame [N], id [N], world [N, 2] (x_c, y_c) and z_c [N] (metres)."""

    frame: np.ndarray
    id: np.ndarray
    world: np.ndarray
    z_c: np.ndarray

    def at(self, frame: int) -> np.ndarray:
        """Row indices of ``frame``."""
        return np.flatnonzero(self.frame == frame)


def cmc_dir(data: Path) -> Path:
    return Path(data) / "cmc"


def available(data: Path) -> bool:
    """Whether the CMC files this bench reads are under ``data``."""
    root = cmc_dir(data)
    return (root / "calibration" / "P_matrices.json").is_file() and all(
        (root / "gt" / f"GT_{code}_WORLD_CENTROID.txt").is_file() for code in SEQUENCES.values()
    )


def projections(data: Path) -> np.ndarray:
    """The four 3 x 4 matrices [4, 3, 4]: pixel = P @ [X, Y, Z, 1] dehomogenised."""
    matrices = json.loads((cmc_dir(data) / "calibration" / "P_matrices.json").read_text())
    return np.array([matrices[f"cam{k + 1}"] for k in range(NUM_CAMERAS)], np.float64)


def read_centroids(path: Path) -> Truth:
    """A ``*_WORLD_CENTROID.txt`` file (truth or the authors' tracker output)."""
    if not path.is_file():
        raise MomlocError(f"{path}: no such file")
    a = np.loadtxt(path, ndmin=2)
    return Truth(a[:, 0].astype(np.int64), a[:, 1].astype(np.int64), a[:, 7:9], a[:, 9])


def truth(data: Path, sequence: str) -> Truth:
    return read_centroids(cmc_dir(data) / "gt" / f"GT_{code(sequence)}_WORLD_CENTROID.txt")


def authors_tracker(data: Path, sequence: str) -> Truth:
    """MV-GLMB-OC estimates of the data set's authors (a calibrated anchor)."""
    name = f"EST_{code(sequence)}_WORLD_CENTROID.txt"
    return read_centroids(cmc_dir(data) / "baseline_mvglmb" / name)


def detection_files(data: Path, sequence: str) -> list[Path]:
    """The real Faster R-CNN boxes, MOT format, one file per camera in camera order."""
    folder = cmc_dir(data) / "detections_mot"
    return [folder / f"DET_{code(sequence)}_Cam{k + 1}.txt" for k in range(NUM_CAMERAS)]


def code(sequence: str) -> str:
    if sequence not in SEQUENCES:
        raise MomlocError(f"sequence {sequence}: not one of {', '.join(SEQUENCES)}")
    return SEQUENCES[sequence]


def in_area(xy: np.ndarray) -> np.ndarray:
    """Bool [N]: inside the authors' tracking area."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    (x0, x1), (y0, y1) = AREA
    return (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)


def project(matrix: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels [N, 2] of world points [N, 3] and whether each is in front of the camera."""
    h = np.c_[points, np.ones(len(points))] @ matrix.T
    return h[:, :2] / h[:, 2:3], h[:, 2] > 0


def expected_boxes(matrix: np.ndarray, world: np.ndarray, z_c: np.ndarray) -> np.ndarray:
    """Each person's expected box [N, 4] in one camera (NaN: behind it or fully outside)."""
    n = len(world)
    foot, front_f = project(matrix, np.c_[world, np.zeros(n)])
    head, front_h = project(matrix, np.c_[world, 2.0 * z_c])
    height = np.abs(foot[:, 1] - head[:, 1])
    cx = 0.5 * (foot[:, 0] + head[:, 0])
    box = np.c_[
        cx - 0.5 * WIDTH_RATIO * height,
        np.minimum(head[:, 1], foot[:, 1]),
        cx + 0.5 * WIDTH_RATIO * height,
        np.maximum(head[:, 1], foot[:, 1]),
    ]
    w, h = IMAGE_SIZE
    clipped = np.c_[np.clip(box[:, [0, 2]], 0, w), np.clip(box[:, [1, 3]], 0, h)][:, [0, 2, 1, 3]]
    empty = (clipped[:, 2] <= clipped[:, 0]) | (clipped[:, 3] <= clipped[:, 1])
    clipped[~(front_f & front_h) | empty] = np.nan
    return clipped


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU [A, B] of xyxy boxes (NaN boxes give 0)."""
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    out = inter / (area_a[:, None] + area_b[None, :] - inter)
    return np.nan_to_num(out, nan=0.0)


def pair_boxes(
    matrix: np.ndarray, world: np.ndarray, z_c: np.ndarray, boxes: np.ndarray
) -> np.ndarray:
    """Per box [M] the row of the person it shows (-1: nobody), for one camera and frame."""
    owner = np.full(len(boxes), -1, np.int64)
    if not len(boxes) or not len(world):
        return owner
    overlap = iou(expected_boxes(matrix, world, z_c), np.asarray(boxes, np.float64))
    rows, cols = linear_sum_assignment(-overlap)
    for r, c in zip(rows, cols, strict=True):
        if overlap[r, c] >= MIN_IOU:
            owner[c] = r
    return owner


def floor_points(matrix: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """The calibrated foot point [M, 2]: each box's bottom centre back-projected onto z = 0."""
    homography = matrix[:, [0, 1, 3]]
    foot = np.c_[0.5 * (boxes[:, 0] + boxes[:, 2]), boxes[:, 3], np.ones(len(boxes))]
    h = foot @ np.linalg.inv(homography).T
    return h[:, :2] / h[:, 2:3]
