"""Whether a model the room taught itself may replace the one in service: never a worse one.

A model refitted on self-labels learns from positions the serving model produced; a bad run (a
wrong association that slipped through, a camera bumped between two checks, an unlucky split)
could make it worse, and the room would then teach the next model from worse positions. So a
candidate is scored on two checks the candidate did not train on, and the model in service is
scored on the very same rows:

- **the floor marks' own check**: the set-up's floor-mark rows, per mark the median distance
  of the localized positions from the mark, summarised by the median over the marks (the
  statistic of the set-up page's check step, :mod:`service.setup.check_score`). The marks are
  the only ground truth the room has; both models saw them in training, so this is a
  "not worse" check, not an estimate of the room's error. "Not worse" within what the check
  can tell apart: the figure's own standard error (each mark's rows scatter by the detector's
  noise), at least 1 mm. Why not exactly: a model fitted on the marks alone is the best
  possible fit *to the marks*, so any model that also fits the rest of the room loses a few
  millimetres there; the first measured run refused a candidate at 0.0714 m against 0.0702 m;
- **held-out self-labels** (:func:`held_out`: whole 15 s blocks of labels the candidate never saw):
  each label's cameras one at a time, the single-view position against the label's multi-view
  position. Why single views: a label *is* the serving model's own fused output, so its fused
  error on it is zero by construction and no candidate could ever win; its single views are
  not, and they are where a room set up on a few marks is weakest (the geometry between and
  beyond the marks).

:func:`judge` serves the candidate only when it is no worse on both checks and better on the
held-out labels by at least ``min_gain`` (relative); otherwise the model in service stays and
the verdict says why, in numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from models.data.dataset import MomDataset
from service.learning.labels import LabelBatch
from service.stages import LocalizationModel

HELD_OUT_BLOCK_S = 15.0  # labels are held out in whole blocks of this long (near-copies inside)
HELD_OUT_EVERY = 5  # every 5th block: ~20 % of the labels
MIN_GAIN = 0.02
MARKS_TOLERANCE_M = 0.001  # the check is reported in millimetres: equal within one


@dataclass(frozen=True)
class Score:
    """A model's two checks (metres; None when there was nothing to check on)."""

    marks_m: float | None
    labels_m: float | None
    marks: int
    labels: int
    marks_se_m: float | None = None  # standard error of marks_m


@dataclass(frozen=True)
class Verdict:
    serve: bool
    reason: str
    current: Score
    candidate: Score

    def as_dict(self) -> dict[str, Any]:
        return {
            "serve": self.serve,
            "reason": self.reason,
            "current": asdict(self.current),
            "candidate": asdict(self.candidate),
        }


def held_out(labels: LabelBatch) -> np.ndarray:
    """[N] bool: the labels kept out of training for the gate (whole ``HELD_OUT_BLOCK_S``
    blocks, every ``HELD_OUT_EVERY``-th counted from the first label's, starting with the
    third: a minute of labels holds one out)."""
    block = np.floor((labels.t - labels.t.min()) / HELD_OUT_BLOCK_S).astype(np.int64)
    return block % HELD_OUT_EVERY == 2


def marks_error(model: LocalizationModel, marks: MomDataset) -> tuple[float, float] | None:
    """Median over the marks of each mark's median localization error (metres), and the
    standard error of that figure (the rows' spread on each mark; :func:`judge`'s tolerance)."""
    seen = marks.visible().any(axis=1)
    if not seen.any():
        return None
    keypoints = marks.keypoints[seen] if marks.keypoints is not None else None
    kwargs = {"keypoints": keypoints} if model.observation == "keypoints" else {}
    xy = np.asarray(model.localize(marks.boxes[seen], **kwargs), np.float64)
    world = marks.world[seen, :2].astype(np.float64)
    error = np.linalg.norm(xy - world, axis=1)
    _, mark = np.unique(np.round(world / 0.05), axis=0, return_inverse=True)
    mark = mark.ravel()
    medians, spreads = [], []
    for m in np.unique(mark):
        rows = error[(mark == m) & np.isfinite(error)]
        if len(rows):
            medians.append(float(np.median(rows)))
            # the standard error of a median: 1.25 std / sqrt(n)
            spreads.append(1.2533 * float(np.std(rows)) / np.sqrt(len(rows)))
    if not medians:
        return None
    return round(float(np.median(medians)), 4), round(float(np.median(spreads)), 4)


def labels_error(
    model: LocalizationModel, labels: LabelBatch, cameras: Sequence[int] | None = None
) -> float | None:
    """Mean distance of each label's single-view positions (of ``cameras``, default all) from
    its multi-view position."""
    views = labels.views()
    if cameras is not None:
        views = views & np.isin(np.arange(labels.num_cameras), list(cameras))[None]
    rows, seen = np.nonzero(views)
    if not len(rows):
        return None
    boxes = np.full((len(rows), labels.num_cameras, 4), np.nan, np.float32)
    boxes[np.arange(len(rows)), seen] = labels.boxes[rows, seen]
    kwargs = {}
    if model.observation == "keypoints":
        points = np.full((len(rows), *labels.keypoints.shape[1:]), np.nan, np.float32)
        points[np.arange(len(rows)), seen] = labels.keypoints[rows, seen]
        kwargs["keypoints"] = points
    xy = np.asarray(model.localize(boxes, **kwargs), np.float64)
    error = np.linalg.norm(xy - labels.world[rows].astype(np.float64), axis=1)
    return round(float(np.nanmean(error)), 4) if np.isfinite(error).any() else None


def score(model: LocalizationModel, marks: MomDataset | None, labels: LabelBatch | None) -> Score:
    on_marks = None if marks is None else marks_error(model, marks)
    return Score(
        marks_m=None if on_marks is None else on_marks[0],
        marks_se_m=None if on_marks is None else on_marks[1],
        labels_m=None if labels is None else labels_error(model, labels),
        marks=0 if marks is None else len(np.unique(np.round(marks.world[:, :2] / 0.05), axis=0)),
        labels=0 if labels is None else labels.n,
    )


def judge(current: Score, candidate: Score, min_gain: float = MIN_GAIN) -> Verdict:
    """Serve ``candidate`` only if no worse on both checks and better on the labels (module
    docstring); the reason says which check decided."""

    def verdict(serve: bool, why: str) -> Verdict:
        return Verdict(serve, why, current, candidate)

    if current.marks_m is None or candidate.marks_m is None:
        return verdict(False, "kept the model in service: no floor-mark check to compare on")
    if current.labels_m is None or candidate.labels_m is None:
        return verdict(False, "kept the model in service: no held-out self-labels to compare on")
    tolerance = max(MARKS_TOLERANCE_M, current.marks_se_m or 0.0)
    if candidate.marks_m > current.marks_m + tolerance:
        return verdict(
            False,
            f"kept the model in service: the new one is worse on the floor marks "
            f"({candidate.marks_m:.3f} m against {current.marks_m:.3f} m)",
        )
    if candidate.labels_m > current.labels_m * (1.0 - min_gain):
        worse = "worse" if candidate.labels_m > current.labels_m else "not better enough"
        return verdict(
            False,
            f"kept the model in service: the new one is {worse} on {candidate.labels} held-out "
            f"self-labels ({candidate.labels_m:.3f} m against {current.labels_m:.3f} m)",
        )
    return verdict(
        True,
        f"serving the new model: floor marks {candidate.marks_m:.3f} m (was "
        f"{current.marks_m:.3f} m), held-out self-labels {candidate.labels_m:.3f} m (was "
        f"{current.labels_m:.3f} m)",
    )
