"""A tiny self-contained synthetic scene for the MoM model tests (no simulator dependency).

Random pinhole cameras on the walls of a room look at its centre; a person is a 0.5 × 0.3 × 1.75 m
box standing on a floor point; each camera's observation is the bounding box of the projected
corners with a little pixel noise, NaN when the person is behind the camera or outside the image.
Keypoints are 17 points spread over the body's box, projected the same way.
"""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

import numpy as np

from models.data.dataset import MomDataset


def look_at_camera(position, target, width, height, fov_deg):
    """3×4 projection matrix of a pinhole camera at ``position`` looking at ``target``."""
    forward = np.asarray(target, float) - np.asarray(position, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rotation = np.stack([right, down, forward])
    focal = width / 2 / np.tan(np.radians(fov_deg) / 2)
    intrinsics = np.array([[focal, 0, width / 2], [0, focal, height / 2], [0, 0, 1]])
    return intrinsics @ np.c_[rotation, -rotation @ np.asarray(position, float)]


def make_dataset(
    n: int = 1000,
    cameras: int = 2,
    seed: int = 0,
    size: tuple[int, int] = (640, 480),
    noise_px: float = 2.0,
    keypoints: bool = False,
    room: float = 6.0,
    rig_seed: int = 0,
) -> tuple[MomDataset, np.ndarray]:
    """``n`` instances on random walks (``seed``) seen by a camera rig (``rig_seed``), and the
    rig's true matrices [K, 3, 4]."""
    rig = np.random.default_rng(rig_seed)
    rng = np.random.default_rng(seed)
    w, h = size
    matrices = []
    for k in range(cameras):
        angle = 2 * np.pi * k / cameras + rig.uniform(-0.3, 0.3)
        position = [
            room / 2 + room * 0.55 * np.cos(angle),
            room / 2 + room * 0.55 * np.sin(angle),
            rig.uniform(1.8, 2.6),
        ]
        matrices.append(look_at_camera(position, [room / 2, room / 2, 0.6], w, h, 90))
    projections = np.stack(matrices)

    tracks = max(1, n // 100)
    track = np.repeat(np.arange(tracks), int(np.ceil(n / tracks)))[:n]
    frame = np.concatenate([np.arange((track == t).sum()) for t in range(tracks)])
    world = np.empty((n, 2))
    for t in range(tracks):  # smooth random walks inside the room
        rows = np.flatnonzero(track == t)
        steps = rng.normal(0, 0.08, (len(rows), 2)).cumsum(axis=0)
        world[rows] = np.abs(
            (rng.uniform(0.5, room - 0.5, 2) + steps) % (2 * room - 2) - (room - 1)
        )
        world[rows] = np.clip(world[rows] + 0.5, 0.3, room - 0.3)

    offsets = np.array(
        [[dx, dy, dz] for dx in (-0.25, 0.25) for dy in (-0.15, 0.15) for dz in (0.0, 1.75)]
    )
    corners = np.c_[world, np.zeros(n)][:, None, :] + offsets  # [N, 8, 3]
    kp_local = rng.uniform([-0.2, -0.1, 0.05], [0.2, 0.1, 1.7], (17, 3))
    kp_world = np.c_[world, np.zeros(n)][:, None, :] + kp_local
    boxes = np.full((n, cameras, 4), np.nan, np.float32)
    kps = np.full((n, cameras, 17, 3), np.nan, np.float32)
    for k, matrix in enumerate(projections):
        pix, depth = _project(matrix, corners)
        box = np.c_[pix.min(axis=1), pix.max(axis=1)] + rng.normal(0, noise_px, (n, 4))
        box[:, 2:] = np.maximum(box[:, 2:], box[:, :2] + 1)
        inside = (depth.min(axis=1) > 0.1) & (box[:, 0] > -50) & (box[:, 2] < w + 50)
        inside &= (box[:, 1] > -50) & (box[:, 3] < h + 50)
        boxes[inside, k] = box[inside]
        kp_pix, _ = _project(matrix, kp_world)
        kp_pix += rng.normal(0, noise_px, kp_pix.shape)
        kps[inside, k] = np.concatenate([kp_pix, np.ones((n, 17, 1))], axis=2)[inside]
    seen = np.any(np.all(np.isfinite(boxes), axis=2), axis=1)
    data = MomDataset(
        world=world[seen].astype(np.float32),
        boxes=boxes[seen],
        frame=frame[seen],
        track=track[seen],
        image_size=np.tile(np.array(size, np.int32), (cameras, 1)),
        keypoints=kps[seen] if keypoints else None,
    )
    return data, projections


def _project(matrix: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    homogeneous = np.concatenate([points, np.ones((*points.shape[:-1], 1))], axis=-1) @ matrix.T
    return homogeneous[..., :2] / homogeneous[..., 2:], homogeneous[..., 2]


@functools.cache
def trained_model(observation: str = "bbox") -> tuple[Path, MomDataset, dict]:
    """Train once per test process on a small scene (a few seconds) and reuse the directory."""
    from models.mom.training.train import train_model

    data, _ = make_dataset(1200, cameras=2, seed=11, keypoints=observation == "keypoints")
    out = Path(tempfile.mkdtemp(prefix="mom-test-")) / observation
    metrics = train_model(data, out, observation=observation, epochs=25, seed=0, progress=False)
    return out, data, metrics
