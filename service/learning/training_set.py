"""The rows a self-improvement run trains on: the floor marks plus self-labels, weighted.

Marks rows stay as recorded: they are the only ground truth, and they fix the floor frame.
Self-labels join as ordinary dataset rows (the box of every camera that saw the person, their
position as ``world``), so ``momloc train`` refits the floor geometry
(:mod:`models.geometry.floor_prior`, which fits dense rows one by one) and the encoder on them.
The improvement run serves the refitted geometry (``--policy prior``,
:mod:`service.learning.improve` says why), not a policy chosen on validation rows.

The labels' positions are first refitted (:func:`aligned`): the serving model fused them, so
they carry its errors, and a floor geometry refitted on them one camera at a time stays close to
the geometry that made them. :mod:`models.geometry.joint_floor` fits every camera's floor map and
every label's position together, on the marks and the cameras' agreement; the training rows get
those positions.

Weighting by covariance: a label whose position is still the one served enters with
probability ``(STD_FULL_M / std)²`` (clipped to ``MIN_KEEP``..1), so the weight of a label in the
fit is its inverse variance relative to a well-placed two-view position. A label the joint fit
placed enters whole: the covariance the serving model gave its fused position does not describe
a position triangulated with the jointly fitted maps, and thinning those by it cost the refitted
geometry 3-6 mm per frame after 5 minutes of walking, 1-8 mm over 2-10 minutes
(``bench/results/joint_floor.md``). Why thinning and not a loss weight: ``momloc train``, the
floor prior's fit and the policy choice all take plain rows; a per-row weight would have to pass
through all three (and the dataset format). Seeded, so a run is reproducible.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.geometry.joint_floor import fit_joint_floor
from service.learning.labels import LabelBatch

log = logging.getLogger("momloc.learning")

STD_FULL_M = 0.05  # labels this sure (or surer) always enter
MIN_KEEP = 0.05
FRAME_RATE = 30.0  # label times -> the dataset's integer frame index


def label_weights(labels: LabelBatch, placed: np.ndarray | None = None) -> np.ndarray:
    """[N] each label's chance to enter the training rows; 1 for the ``placed`` ones ([N] bool,
    positions the joint fit triangulated; module docstring)."""
    std = np.maximum(labels.std_m(), 1e-6)
    weights = np.clip((STD_FULL_M / std) ** 2, MIN_KEEP, 1.0)
    return weights if placed is None else np.where(placed, 1.0, weights)


def aligned(
    marks: MomDataset, labels: LabelBatch, seed: int = 0
) -> tuple[LabelBatch, np.ndarray, str]:
    """``labels`` with the positions of the joint floor fit on ``marks`` and them, which of
    them it placed ([N] bool), and a line saying what it did; the labels as they are, none
    placed (and why), when the fit cannot run."""
    try:
        joint = fit_joint_floor(
            marks.world, marks.boxes, labels.world, labels.boxes, marks.image_size, seed=seed
        )
    except MomlocError as error:
        log.warning("self-improvement: positions as served (%s)", error)
        return labels, np.zeros(labels.n, bool), f"positions as served ({error})"
    taught = dataclasses.replace(labels, world=joint.world.astype(labels.world.dtype))
    return taught, joint.placed, joint.describe()


def training_set(
    marks: MomDataset,
    labels: LabelBatch | None,
    seed: int = 0,
    placed: np.ndarray | None = None,
) -> MomDataset:
    """``marks`` with the (weighted) ``labels`` appended as rows (the ``placed`` ones whole);
    labels of another camera count are refused with ``ValueError``."""
    if labels is None or labels.n == 0:
        return marks
    if labels.num_cameras != marks.num_cameras:
        raise ValueError(
            f"self-labels have {labels.num_cameras} cameras, the marks {marks.num_cameras}"
        )
    rng = np.random.default_rng(seed)
    kept = labels.subset(rng.random(labels.n) < label_weights(labels, placed))
    if kept.n == 0:
        return marks
    dims = marks.world.shape[1]
    world = np.zeros((kept.n, dims), np.float32)
    world[:, :2] = kept.world
    frame = marks.frame.max() + 1 + np.round((kept.t - kept.t.min()) * FRAME_RATE).astype(np.int64)
    track = marks.track.max() + 1 + kept.track - kept.track.min()
    keypoints = None
    if marks.keypoints is not None:
        joints = marks.keypoints.shape[2]
        keypoints = np.concatenate(
            [marks.keypoints, _joints(kept.keypoints, joints)], axis=0
        ).astype(np.float32)
    return MomDataset(
        world=np.concatenate([marks.world, world]).astype(np.float32),
        boxes=np.concatenate([marks.boxes, kept.boxes]).astype(np.float32),
        frame=np.concatenate([marks.frame, frame]).astype(np.int64),
        track=np.concatenate([marks.track, track]).astype(np.int64),
        image_size=marks.image_size,
        keypoints=keypoints,
    )


def _joints(points: np.ndarray, joints: int) -> np.ndarray:
    """Label keypoints [N, K, J', 3] as [N, K, joints, 3] (NaN where the label has none)."""
    if points.shape[2] == joints:
        return points
    out = np.full((*points.shape[:2], joints, 3), np.nan, np.float32)
    shared = min(joints, points.shape[2])
    out[:, :, :shared] = points[:, :, :shared]
    return out
