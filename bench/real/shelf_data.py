"""Readers for Shelf as packaged by the 4D Association Graph repository
(``../shared/data/shelf``, formats in its ``SOURCE.txt``): the 5 calibrated cameras, the true
3D skeletons (15 joints) and the real OpenPose BODY25 detections per camera (joints not grouped
into people). numpy only; the files are whitespace-separated numbers, read as one token stream.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.real.data import Calibration

# BODY25 part-affinity limbs (src/skel.h): one n_A × n_B score matrix per pair follows the joints.
PAF_A = (1, 9, 10, 8, 8, 12, 13, 1, 2, 3, 2, 1, 5, 6, 5, 1, 0, 0, 15, 16, 14, 19, 14, 11, 22, 11)
PAF_B = (8, 10, 11, 9, 12, 13, 14, 2, 3, 4, 17, 5, 6, 7, 18, 0, 15, 16, 17, 18, 19, 20, 21, 22,
         23, 24)  # fmt: skip
BODY25_JOINTS = 25
SHELF_JOINTS = 15
# Shelf joint -> BODY25 joint with the same meaning (13, the top of the head, has none).
SHELF_TO_BODY25 = {0: 11, 1: 10, 2: 9, 3: 12, 4: 13, 5: 14, 6: 4, 7: 3, 8: 2, 9: 5, 10: 6,
                   11: 7, 12: 1, 14: 8}  # fmt: skip
SHELF_NAMES = (
    "R ankle", "R knee", "R hip", "L hip", "L knee", "L ankle", "R wrist", "R elbow",
    "R shoulder", "L shoulder", "L elbow", "L wrist", "neck", "head top", "pelvis",
)  # fmt: skip
TOP_HEAD, PELVIS = 13, 14


def load_cameras(folder: Path) -> list[Calibration]:
    """The five cameras of ``calibration.json`` (K, RT row-major, imgSize), in key order."""
    raw = json.loads((folder / "calibration.json").read_text())
    out = []
    for key in sorted(raw, key=int):
        cam = raw[key]
        rt = np.asarray(cam["RT"], float).reshape(3, 4)
        size = (int(cam["imgSize"][0]), int(cam["imgSize"][1]))
        out.append(Calibration(key, np.asarray(cam["K"], float).reshape(3, 3), rt[:, :3],
                               rt[:, 3], size))  # fmt: skip
    return out


@dataclass(frozen=True)
class Skeletons:
    """True 3D people of one frame: ``ids`` [P], ``joints`` [P, 15, 3] metres, ``valid`` [P, 15]."""

    ids: np.ndarray
    joints: np.ndarray
    valid: np.ndarray


def load_truth(path: Path) -> list[Skeletons]:
    """``gt_shelf15_3d.txt``: per frame the people, each a 4 × 15 matrix (x, y, z, validity)."""
    tokens = iter(path.read_text().split())
    joints, frames = int(next(tokens)), int(next(tokens))
    out = []
    for _ in range(frames):
        people = int(next(tokens))
        ids, points, valid = [], [], []
        for _ in range(people):
            ids.append(int(next(tokens)))
            matrix = np.array([float(next(tokens)) for _ in range(4 * joints)]).reshape(4, joints)
            points.append(matrix[:3].T)
            valid.append(matrix[3] > 0)
        out.append(
            Skeletons(
                np.array(ids, np.int64),
                np.array(points, float).reshape(-1, joints, 3),
                np.array(valid, bool).reshape(-1, joints),
            )
        )
    return out


def load_detections(path: Path, image_size: tuple[int, int]) -> list[list[np.ndarray]]:
    """One camera's OpenPose file: per frame, per BODY25 joint the candidates [n, 3] (x, y in
    pixels, score); the part-affinity scores are read past (this bench groups by geometry)."""
    tokens = iter(path.read_text().split())
    int(next(tokens))  # skeleton type (4 = BODY25)
    frames = int(next(tokens))
    scale = np.array([image_size[0] - 1, image_size[1] - 1, 1.0])
    out = []
    for _ in range(frames):
        per_joint = []
        for _ in range(BODY25_JOINTS):
            n = int(next(tokens))
            rows = np.array([float(next(tokens)) for _ in range(3 * n)]).reshape(3, n)
            per_joint.append(rows.T * scale)
        for a, b in zip(PAF_A, PAF_B, strict=True):
            for _ in range(len(per_joint[a]) * len(per_joint[b])):
                next(tokens)
        out.append(per_joint)
    return out
