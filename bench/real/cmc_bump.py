"""A simulated bump of one real camera: its boxes moved by the homography of a small roll.

The CMC data set has boxes, not images, so a bumped camera is simulated on its boxes: a camera
rolled by ``roll_deg`` about its optical axis and shifted by ``dx`` pixels sees the old image
turned about the image centre and moved, a homography of the image plane (here a similarity,
the same bump as the simulator's :class:`models.simulate.Perturbation`: roll 3°, shift 10 px).
Each box becomes the bounding box of its four moved corners, clipped to the image: what a
detector would draw around the turned person, up to the person's shape inside the box.

Boxes keep their order and number (a box moved out of the image is clipped to an empty box at
the edge, never dropped), so the evaluation pairing computed on the unbumped boxes still says
whose box each is (``bench.real.cmc_chain.Ground`` indexes boxes by position).
"""

from __future__ import annotations

import numpy as np

from models.data.dataset import MomDataset
from models.data.detections_replay import DetectionsReplay

ROLL_DEG = 3.0
SHIFT_PX = 10.0


def bump_homography(
    image_size: tuple[int, int], roll_deg: float = ROLL_DEG, dx: float = SHIFT_PX
) -> np.ndarray:
    """H [3, 3]: the image turned by ``roll_deg`` about its centre, then moved ``dx`` px right."""
    w, h = image_size
    c, s = np.cos(np.radians(roll_deg)), np.sin(np.radians(roll_deg))
    centre = np.array([w / 2.0, h / 2.0])
    rotation = np.array([[c, -s], [s, c]])
    out = np.eye(3)
    out[:2, :2] = rotation
    out[:2, 2] = centre + np.array([dx, 0.0]) - rotation @ centre
    return out


def move_boxes(
    boxes: np.ndarray, homography: np.ndarray, image_size: tuple[int, int]
) -> np.ndarray:
    """Boxes [M, 4] (xyxy) moved by ``homography``: the bounding box of the moved corners,
    clipped to the image (NaN rows stay NaN)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    corners = np.stack(
        [b[:, [0, 1]], b[:, [2, 1]], b[:, [2, 3]], b[:, [0, 3]]], axis=1
    )  # [M, 4, 2]
    h = np.concatenate([corners, np.ones((*corners.shape[:2], 1))], axis=2) @ homography.T
    moved = h[..., :2] / h[..., 2:3]
    w, height = image_size
    lo = moved.min(axis=1)
    hi = moved.max(axis=1)
    out = np.c_[lo, hi]
    out[:, [0, 2]] = np.clip(out[:, [0, 2]], 0.0, w)
    out[:, [1, 3]] = np.clip(out[:, [1, 3]], 0.0, height)
    return out


def bumped_replay(
    replay: DetectionsReplay, camera: int, from_frame: int, homography: np.ndarray
) -> DetectionsReplay:
    """``replay`` with ``camera``'s boxes from ``from_frame`` on moved (rows in place)."""
    rows = (replay.camera == camera) & (replay.frame >= from_frame)
    size = tuple(int(v) for v in replay.image_size[camera])
    boxes = replay.boxes.astype(np.float64)
    boxes[rows] = move_boxes(boxes[rows], homography, (size[0], size[1]))
    return DetectionsReplay(
        replay.frame, replay.camera, boxes, replay.scores, replay.image_size, replay.fps
    )


def bumped_dataset(data: MomDataset, camera: int, homography: np.ndarray) -> MomDataset:
    """``data`` (labelled rows) with ``camera``'s boxes moved; keypoints dropped."""
    size = tuple(int(v) for v in data.image_size[camera])
    boxes = data.boxes.astype(np.float64).copy()
    boxes[:, camera] = move_boxes(boxes[:, camera], homography, (size[0], size[1]))
    return MomDataset(data.world, boxes, data.frame, data.track, data.image_size)
