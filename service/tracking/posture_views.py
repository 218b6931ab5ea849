"""A person two cameras see compact is lying when only the lying reading makes the views agree.

Why: a body on the floor seen lengthwise or obliquely gives a short box about as wide as tall,
the shape of a seated person's or a squat's (:mod:`service.tracking.posture`), and when every
camera sees it so, every box reads sitting and the association is voted sitting: no fall. The
seated conversion keeps each box's top as a head 0.64 of a standing height up, but the top of
such a box is the far end of a body on the floor, so each camera alone puts the person 1-1.7 m
towards itself, and the two cameras' seated readings land 2-2.8 m apart, while the lying
readings (the floor under the body's middle, :data:`~service.tracking.posture.LYING_FOOT` down
each box) land together. A seated person is the other way round: the seated readings agree,
and the lying ones land 1.1-2.8 m apart (the floor point 0.7 down a seated box is beyond the
seat, away from each camera). A squat sits between.

Measured on the simulated lounge with the true association (each person's own two boxes, each
localized alone; scenes none of the fall bench's seeds; ``bench/results/posture_views.md``, by
``bench.serving.posture_views``): a lying body's seated readings land 2-2.8 m apart and its
lying readings within 0.4 m (5-95 %); a squat's seated readings within 1.6 m, its lying ones
0.6 m apart or more; a sitter's lying readings 1.1 m apart or more. The rule (lying readings
within ``AGREE_M``, seated ones ``APART_M`` apart or more) takes 92 % of the lying frames, every
one of those no box read lying (the missed falls' case), and none of daily life's two-view
frames, squats and sitters alike. With the seated bound at 1.5 m it took 98.5 % of the lying
frames, but in the fall bench's sets 1301 and 1501 a squat between the two cameras, near their
wall, seen from both sides, agreed as lying (0.34-0.46 m) with its seated readings 1.7 m apart:
two false falls (``bench/results/falls.md``). An association whose boxes read lying and sitting
(voted lying) is converted wholly as lying by the same test: otherwise its seated boxes keep
their seated conversion and pull the body towards their cameras.

A squat seen from both sides near the cameras' wall still passes both bounds now and then
(lying readings 0.36-0.5 m apart, seated ones over 2 m): in held-out daily life of the lounge
(seed 3801) one did for seconds, read lying by both cameras, and was a false fall
(``bench/results/falls.md``, 2026-12-07 night). What a squat has and a body on the floor has
not is feet at its boxes' bottoms: each camera's *feet reading* (a standing person whose feet
are the box's bottom, ``FEET``) lands on the squat, while a body on the floor shows each camera
its near end, and the cameras' near ends are different parts of it. So the lying reading is
taken only where the views' lying readings agree at least as well as their feet readings. On
the bodies of the fall bench's seeds 1801-1808 through the chain, 96 % of the frames the two
bounds took pass (their feet readings 0.8 m apart, median; lying ones 0.23 m); of the 16 frames
of squats they took in that hour, 8.

Rejected: the converse, a lying vote read seated when its lying readings land 0.8 m apart or
more (a body's never did beyond 0.6 m; 7 of daily life's 10 two-view frames with a box of a squat
or a sit-down read lying did): a falling body's first lying reads land apart too, and falls were
reported later (set 601: two of 24 beyond 3 s); a ratio of the two spreads (seated ≥ 2 × lying
took 19 % of the crouch frames); the box centre as the lying floor point here (its readings of
a lying body land 0.53 m apart, median: the centre is too far up a body seen obliquely). A lone
view has no second reading to agree with: :mod:`service.tracking.posture_continuity` judges it
by where the track was.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from models.detector.base import Detections
from models.mom.setup_area import SetupArea
from service.stages import Association
from service.tracking.posture import LYING, LYING_FOOT, SITTING, BoxPostures, standing_boxes
from service.tracking.posture_agreement import Relocalizing

AGREE_M = 0.5  # the cameras' lying readings at most this far apart ...
APART_M = 2.0  # ... and their seated readings at least this far apart
SURE_M = 0.5  # beyond each bound by this much, the lying read is sure (confidence 1)
FEET = 1.0  # a squat's floor point: its box's bottom (its feet), not LYING_FOOT down it


def lying_by_views(
    associations: Sequence[Association],
    detected: Sequence[Detections],
    postures: BoxPostures,
    area: SetupArea | None,
    runtime: Relocalizing,
) -> list[Association]:
    """``associations`` with each one seen compact by two or more cameras converted as a body
    on the floor where only that reading makes its views agree (module docstring);
    ``postures`` is updated to say ``lying`` for the boxes of each association so read."""
    out = list(associations)
    if area is None or runtime.observation != "bbox":
        return out
    for n, association in enumerate(out):
        boxes = _compact_views(association, detected, postures)
        if boxes is None:
            continue
        cameras = sorted(boxes)
        seated = _lone_rows(boxes, SITTING, area, len(association.boxes))
        lying = _lone_rows(boxes, LYING, area, len(association.boxes))
        feet = _lone_rows(boxes, LYING, area, len(association.boxes), FEET)
        readings = np.concatenate([seated, lying, feet])
        world = np.asarray(runtime.localize(readings), np.float64)[:, :2]
        if not np.isfinite(world).all():
            continue
        views = len(cameras)
        seated_apart = float(_pairwise(world[:views]).min())
        lying_apart = float(_pairwise(world[views : 2 * views]).max())
        feet_apart = float(_pairwise(world[2 * views :]).max())
        if not (lying_apart <= AGREE_M and seated_apart >= APART_M and feet_apart >= lying_apart):
            continue
        rows = np.full_like(lying[0], np.nan)
        for row, k in enumerate(cameras):
            rows[k] = lying[row, k]
        relocalized = np.asarray(runtime.localize(rows[None]), np.float64)[0]
        if not np.isfinite(relocalized).all():
            continue
        covariance = np.asarray(runtime.covariance(rows[None]), np.float64)[0]
        out[n] = dataclasses.replace(
            association, boxes=rows, world=relocalized, covariance=covariance
        )
        margin = min(seated_apart - APART_M, AGREE_M - lying_apart) / SURE_M
        sure = round(0.5 + 0.5 * min(max(margin, 0.0), 1.0), 3)
        for k in cameras:
            index = association.detection_index[k]
            assert index is not None
            postures.labels[k][index] = LYING
            postures.confidence[k][index] = sure
    return out


def _compact_views(
    association: Association, detected: Sequence[Detections], postures: BoxPostures
) -> dict[int, np.ndarray] | None:
    """The association's boxes as detected, by camera, when there are two or more, each reads
    sitting or lying and at least one sitting (all lying: already converted so); else None."""
    boxes = postures.low(association.detection_index, detected)
    if boxes is None or len(boxes) < 2:
        return None
    labels = {str(postures.labels[k][association.detection_index[k]]) for k in boxes}
    return boxes if SITTING in labels else None


def _lone_rows(
    boxes: dict[int, np.ndarray],
    label: str,
    area: SetupArea,
    num_cameras: int,
    lying_foot: float = LYING_FOOT,
) -> np.ndarray:
    """[len(boxes), K, 4]: each box converted as ``label`` says (a lying one's floor point
    ``lying_foot`` down it), alone in its row."""
    rows = np.full((len(boxes), num_cameras, 4), np.nan)
    label_of = np.array([label], dtype=object)
    for row, k in enumerate(sorted(boxes)):
        rows[row, k] = standing_boxes(boxes[k][None], label_of, area, k, lying_foot)[0]
    return rows


def _pairwise(points: np.ndarray) -> np.ndarray:
    """The distances between every two of ``points`` [N, 2]."""
    upper = np.triu_indices(len(points), 1)
    return np.linalg.norm(points[:, None] - points[None], axis=-1)[upper]
