"""The product's chain on real geometry, and the oracle bounds that explain its misses.

Shared by ``bench.real.multiviewx`` and ``bench.real.wildtrack``:

- :func:`train_runtime` trains the way ``momloc train`` does
  (``models.mom.training.train.train_model`` defaults, a time budget so a bench stays bounded) and
  loads the served model;
- :func:`serve` runs the daemon's association (``service.tracking.association.associate``) and
  set-up area gate (``service.pipeline.chain.gate_to_area``) on one frame set's detections, and
  :func:`breakdown` says why each wrong or missing position is one;
- :func:`match_people` pairs one camera's boxes with the true people projected through the real
  calibration (the box's bottom centre near the projected floor point, in units of the person's
  projected height), which gives the detector's recall and the *true association* of the boxes;
- :func:`foot_point` is the calibrated reference a classical system would serve: each box's
  bottom centre back-projected to the floor through the real calibration
  (:func:`floor_points`), averaged over the cameras of one person; the same back-projection
  serves as an oracle *validity gate* (keep only the boxes whose foot lies on the set-up floor).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from bench.real.data import Calibration
from models.data.dataset import MomDataset
from models.detector.base import Detections
from models.mom.runtime import MomRuntime
from service.stages import Association

PERSON_HEIGHT_M = 1.8  # the annotation cylinders' height (Wildtrack, MultiviewX)
MATCH_GATE = 0.3  # box bottom centre within 0.3 projected heights of the floor point


def train_runtime(
    dataset: MomDataset, out: Path, seconds: float, seed: int = 0
) -> tuple[MomRuntime, int]:
    """``momloc train`` on ``dataset`` with its adaptive schedule cut at ``seconds`` of wall
    time (so on a busy machine fewer epochs run: the count is returned to be reported)."""
    from models.mom.training.train import train_model

    info = train_model(dataset, out, seed=seed, progress=False, tuning={"time_budget_s": seconds})
    return MomRuntime.load(out), int(info["epochs_run"])


def serve(detections: Sequence[Detections], runtime: Any) -> list[Association]:
    """The daemon's association of one frame set's detections and its set-up area gate (what
    it localizes and tracks: ``service.pipeline.chain``, people outside the area dropped)."""
    from service.pipeline.chain import gate_to_area
    from service.tracking.association import associate

    return gate_to_area(associate(list(detections), runtime), runtime, "drop")


def positions(associations: Sequence[Association]) -> np.ndarray:
    """Served floor positions [M, 2]."""
    return np.array([a.world for a in associations], dtype=np.float64).reshape(-1, 2)


FP_CAUSES = ("no true person", "mixed people", "duplicate", "one person, off > 0.5 m")
FN_CAUSES = ("no box in any camera", "boxed, not served within 0.5 m")


def breakdown(
    associations: Sequence[Association],
    labels: Sequence[np.ndarray],
    matched: np.ndarray,
    truth_matched: np.ndarray,
    people: int,
) -> tuple[Counter[str], Counter[str], Counter[str]]:
    """Why each unmatched served position (FP) and unmatched true person (FN) is one.

    ``labels[k]`` is the true person of each of camera k's boxes (-1: nobody,
    :func:`match_people`); ``matched`` [M] the served positions scoring a TP, ``truth_matched``
    the true people they matched. FP: all its boxes belong to nobody; it fuses boxes of two
    people (or a person and a false box); its person is already served by another position; or
    it is one person placed more than 0.5 m off. FN: no camera has a box of them, or they have
    one but no position within 0.5 m. Also counts the FPs by how many cameras they fuse."""
    fp: Counter[str] = Counter()
    fn: Counter[str] = Counter()
    fp_views: Counter[str] = Counter()
    is_tp = np.zeros(len(associations), bool)
    is_tp[matched] = True
    served_people = set(np.asarray(truth_matched).tolist())
    for a, tp in zip(associations, is_tp, strict=True):
        if tp:
            continue
        who = {int(labels[k][j]) for k, j in enumerate(a.detection_index) if j is not None}
        fp_views[str(min(len(a.cameras), 3)) + ("+" if len(a.cameras) >= 3 else "")] += 1
        if who == {-1}:
            fp[FP_CAUSES[0]] += 1
        elif len(who) > 1:
            fp[FP_CAUSES[1]] += 1
        elif who <= served_people:
            fp[FP_CAUSES[2]] += 1
        else:
            fp[FP_CAUSES[3]] += 1
    boxed = set(np.concatenate([np.asarray(lab) for lab in labels] or [np.zeros(0)]).tolist())
    for p in range(people):
        if p in served_people:
            continue
        fn[FN_CAUSES[0] if p not in boxed else FN_CAUSES[1]] += 1
    return fp, fn, fp_views


def projected_people(
    calibration: Calibration, xy: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Floor point [P, 2] px, projected height [P] px and in-view flag [P] of people at ``xy``:
    in view when the point at half the height is in front of the camera and inside the image."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    zeros = np.zeros((len(xy), 1))
    foot, depth = calibration.project(np.c_[xy, zeros])
    head, _ = calibration.project(np.c_[xy, zeros + PERSON_HEIGHT_M])
    middle, _ = calibration.project(np.c_[xy, zeros + PERSON_HEIGHT_M / 2])
    w, h = calibration.image_size
    inside = (middle[:, 0] >= 0) & (middle[:, 0] < w) & (middle[:, 1] >= 0) & (middle[:, 1] < h)
    height = np.linalg.norm(head - foot, axis=1)
    return foot, height, (depth > 0.1) & inside


def match_people(
    boxes: np.ndarray, calibration: Calibration, xy: np.ndarray, gate: float = MATCH_GATE
) -> np.ndarray:
    """[M] index of the true person each box [M, 4] belongs to (-1: nobody), one to one."""
    boxes = np.asarray(boxes, float).reshape(-1, 4)
    out = np.full(len(boxes), -1, np.int64)
    foot, height, seen = projected_people(calibration, xy)
    if not len(boxes) or not seen.any():
        return out
    bottom = np.c_[(boxes[:, 0] + boxes[:, 2]) / 2, boxes[:, 3]]
    cost = np.linalg.norm(bottom[:, None] - foot[None], axis=2) / np.maximum(height, 1.0)[None]
    cost = np.where(seen[None] & (cost <= gate), cost, 1e6)
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] <= gate
    out[rows[keep]] = cols[keep]
    return out


def true_tuples(
    boxes: Sequence[np.ndarray], labels: Sequence[np.ndarray], people: int
) -> tuple[np.ndarray, np.ndarray]:
    """The boxes grouped by true person: tuples [B, K, 4] (NaN: not seen) of the B people at
    least one camera's box belongs to, and their person indices [B]."""
    tuples = np.full((people, len(boxes), 4), np.nan)
    for k, (b, lab) in enumerate(zip(boxes, labels, strict=True)):
        mine = lab >= 0
        tuples[lab[mine], k] = np.asarray(b, float).reshape(-1, 4)[mine]
    found = np.flatnonzero(np.isfinite(tuples).all(axis=2).any(axis=1))
    return tuples[found], found


def floor_points(boxes: np.ndarray, calibration: Calibration) -> np.ndarray:
    """Each box's [M, 4] bottom centre through the inverse floor homography (z = 0) → [M, 2]."""
    b = np.asarray(boxes, float).reshape(-1, 4)
    floor = calibration.K @ np.c_[calibration.R[:, :2], calibration.t]  # floor (x, y, 1) -> px
    pixels = np.c_[(b[:, 0] + b[:, 2]) / 2, b[:, 3], np.ones(len(b))]
    world = pixels @ np.linalg.inv(floor).T
    with np.errstate(divide="ignore", invalid="ignore"):
        return world[:, :2] / world[:, 2:3]


def foot_point(tuples: np.ndarray, calibrations: Sequence[Calibration]) -> np.ndarray:
    """Calibrated reference [B, 2]: :func:`floor_points` of each seen box of a tuple [B, K, 4],
    averaged over its cameras."""
    points = np.stack([floor_points(tuples[:, k], c) for k, c in enumerate(calibrations)], axis=1)
    with np.errstate(invalid="ignore"):
        return np.nanmean(points, axis=1)
