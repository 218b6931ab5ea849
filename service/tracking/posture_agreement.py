"""One posture per person: the boxes of an association that disagree are read as the majority's.

Why: :mod:`service.tracking.posture` judges each box alone, and a seated person's box is not
short in every view. In the simulated lounge the person in the armchair is ~0.8 of a standing
height to the camera they face away from (their feet are further than their hips, so the
expected height at the box bottom is smaller), which reads as standing, while the other camera
sees a short, wide seated box. Localized from one standing box and one head-based box, that
person was put far off (``bench/results/postures.md``: the seated error by camera labels).
Once the boxes are associated, the person's posture is the vote over their boxes
(:meth:`~service.tracking.posture.BoxPostures.of`); a box of another label is converted as that
posture says (a seated person's standing box from its top), and the association is localized
again from the converted boxes.

A box as tall as a standing person there in an association with a seated or lying box is
another person: the association paired a seated person's box with a walker's or with a false
box of a standing person's size (its reprojection check cannot tell, the seated box having been
converted into a standing one), which put the seated person up to 1 m off in the simulated
lounge. Such an association is split into its low and its tall boxes, each localized alone,
as if the association had refused the pair.

A box the image border cuts (``unknown``: :mod:`service.tracking.posture` does not judge it)
in an association voted lying is left out of its position: the rest of a body on the floor
cut by the frame has neither its feet at the bottom nor its head at the top, and read as a
standing person's box it put the body 1.0-1.3 m from where it lay in a fall of the simulated
lounge (a two-camera pair with the camera that saw it whole, which alone put it 0.25 m off),
so the fall was reported too far away to be that fall (``bench/results/falls.md``). The
association keeps the other boxes, localized again. A seated vote keeps a cut box: a seated
person cut at the side keeps their head at the top of the box.

Only a box short for a standing person there (below ``AGREE_RATIO`` of the expected height) is
converted: a walker's box that the association mistakenly voted seated (a mispaired short box
in the other view) keeps its own. Walkers measured in the simulated indoor rooms are below 0.9
in ~3 % of boxes; the seated person's "standing" views are 0.74-0.84.

Rejected: a lower per-box threshold for sitting (raising ``SEATED_RATIO`` from 0.78 to 0.9
catches those views but reads ~1.5 % more of the simulated walkers' boxes as seated, each
then localized from its head); the track's posture as a prior (the box-to-track link is only
known after the association). The cost is one or two extra localization calls per mixed
association and a height-model lookup per standing box of a multi-box association.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from models.detector.base import Detections
from models.mom.setup_area import SetupArea
from service.stages import Association, WithCovariance
from service.tracking.posture import (
    LYING,
    SITTING,
    STANDING,
    UNKNOWN,
    BoxPostures,
    camera_postures,
    standing_boxes,
    standing_height_at,
)


class Relocalizing(WithCovariance, Protocol):
    """What :func:`agree` needs of the model (``MomRuntime``): its observation kind, positions
    and their covariances."""

    @property
    def observation(self) -> str: ...

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray: ...


AGREE_RATIO = 0.9  # a "standing" box shorter than this (of a standing person's height) can be
# a seated person's view that the per-box thresholds missed


def agree(
    associations: Sequence[Association],
    detected: Sequence[Detections],
    postures: BoxPostures,
    area: SetupArea | None,
    runtime: Relocalizing,
) -> list[Association]:
    """``associations`` with each mixed one (a seated or lying vote with standing boxes short
    enough to be another view of it) rebuilt from the boxes as ``detected`` (before the
    posture stage), all converted as the vote says, and localized again; one with low and
    tall boxes split in two (appended at the end)."""
    out = list(associations)
    if area is None or runtime.observation != "bbox":  # keypoint models read the joints
        return out
    split: list[Association] = []
    for n, association in enumerate(associations):
        tall = [
            k
            for k, i in enumerate(association.detection_index)
            if i is not None
            and str(postures.labels[k][i]) == STANDING
            and not _short(np.asarray(detected[k].boxes[i], np.float64).reshape(1, 4), area, k)
        ]
        low = [
            k
            for k, i in enumerate(association.detection_index)
            if i is not None and str(postures.labels[k][i]) in (SITTING, LYING)
        ]
        if tall and low:  # a standing person's box and a seated one
            out[n] = _part(association, low, runtime)
            split.append(_part(association, tall, runtime))
            continue
        label, _ = postures.of(association.detection_index)
        if label not in (SITTING, LYING):
            continue
        if label == LYING:  # a cut box says nothing of where a body lies (module docstring)
            whole = [
                k
                for k, i in enumerate(association.detection_index)
                if i is not None and str(postures.labels[k][i]) != UNKNOWN
            ]
            if len(whole) < sum(i is not None for i in association.detection_index):
                association = out[n] = _part(association, whole, runtime)
        rows = np.array(association.boxes, np.float64, copy=True)
        changed = False
        for k, i in enumerate(association.detection_index):
            if i is None or k in tall or str(postures.labels[k][i]) != STANDING:
                continue
            box = np.asarray(detected[k].boxes[i], np.float64).reshape(1, 4)
            rows[k] = standing_boxes(box, np.array([label], dtype=object), area, k)[0]
            changed = True
        if changed:
            out[n] = _relocalized(association, rows, runtime)
    return out + split


def agreed_rows(
    boxes: np.ndarray,
    area: SetupArea | None,
    image_sizes: np.ndarray | None = None,
    keypoints: np.ndarray | None = None,
) -> np.ndarray:
    """Rows of boxes [N, K, 4] (one person per row, NaN where unseen: the true association;
    ``keypoints`` [N, K, 17, 3] when the detections carry them) as the chain localizes them:
    every box converted as its posture says (:func:`~service.tracking.posture.camera_postures`),
    then the short standing boxes of a seated or lying row as the row's vote says (what
    :func:`agree` does to an association)."""
    boxes = np.asarray(boxes, np.float64)
    out = np.array(boxes, copy=True)
    per_camera = [
        camera_postures(
            boxes[:, k],
            area,
            k,
            None if image_sizes is None else image_sizes[k],
            None if keypoints is None else keypoints[:, k],
        )
        for k in range(boxes.shape[1])
    ]
    postures = BoxPostures([c[0] for c in per_camera], [c[1] for c in per_camera])
    for k, (_, _, fixed) in enumerate(per_camera):
        out[:, k] = fixed
    if area is None:
        return out
    for n in range(len(boxes)):
        index = [n if np.isfinite(boxes[n, k]).all() else None for k in range(boxes.shape[1])]
        label, _ = postures.of(index)
        if label not in (SITTING, LYING):
            continue
        for k, i in enumerate(index):
            if i is not None and label == LYING and str(postures.labels[k][i]) == UNKNOWN:
                out[n, k] = np.nan  # as :func:`agree`: a cut box out of a body on the floor
            elif i is not None and str(postures.labels[k][i]) == STANDING:
                box = boxes[n, k].reshape(1, 4)
                if _short(box, area, k):
                    out[n, k] = standing_boxes(box, np.array([label], dtype=object), area, k)[0]
    return out


def _short(box: np.ndarray, area: SetupArea, camera: int) -> bool:
    expected = standing_height_at(box, area, camera)
    if expected is None:
        return False
    return bool(box[0, 3] - box[0, 1] < AGREE_RATIO * float(expected[0]))


def _part(association: Association, cameras: list[int], runtime: Relocalizing) -> Association:
    """The association reduced to ``cameras`` (its other boxes dropped), localized again."""
    keep = np.zeros(len(association.detection_index), dtype=bool)
    keep[cameras] = True
    rows = np.where(keep[:, None], np.asarray(association.boxes, np.float64), np.nan)
    part = dataclasses.replace(
        association,
        cameras=[int(k) for k in cameras],
        detection_index=[i if keep[k] else None for k, i in enumerate(association.detection_index)],
        errors=np.where(keep, association.errors, np.nan)
        if len(association.errors)
        else association.errors,
    )
    return _relocalized(part, rows, runtime)


def _relocalized(association: Association, rows: np.ndarray, runtime: Relocalizing) -> Association:
    world = np.asarray(runtime.localize(rows[None]), np.float64)[0]
    if not np.isfinite(world).all():
        return association
    covariance = np.asarray(runtime.covariance(rows[None]), np.float64)[0]
    return dataclasses.replace(association, boxes=rows, world=world, covariance=covariance)
