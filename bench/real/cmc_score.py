"""Per-frame detection scoring on the floor, with the error attribution of issue 23.

Per frame, the estimates inside the scored area and the true people are matched one to one by
the Hungarian algorithm on floor distance, pairs beyond ``gate_m`` (0.5 m) never. Over all
frames (``gt`` true people, ``tp`` matched, ``fp`` estimates left, ``fn`` people left):

``precision``, ``recall``   ``tp / (tp + fp)``, ``tp / gt`` in percent
``moda``                    ``1 - (fp + fn) / gt`` in percent (CLEAR MOT, no identities)
``modp``                    ``sum(1 - d / gate) / tp`` in percent (the Wildtrack / MVDet form)
``matched_mean_m``          mean floor error of the matched pairs

Attribution, from the evaluation pairing of boxes to people (``bench.real.cmc_data.pair_boxes``):
an unmatched estimate is ``nobody`` (none of its boxes shows a true person), ``mixed`` (its
boxes show two or more people), ``duplicate`` (its one person is matched by another estimate)
or ``off`` (its one person, estimated more than the gate away). A missed person is
``with_box`` (some camera has a box of theirs: the chain lost it) or ``without_box`` (no
camera's detector saw them: no chain can serve them).

Why per frame and streamed apart: the per-frame figures score the localizer's associations
before tracking, the streamed ones (``models.data.stream_metrics``) what a client receives.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

GATE_M = 0.5
MAX_CAMERAS_CLASS = 4
FP_KINDS = ("nobody", "mixed", "duplicate", "off")
FN_KINDS = ("with_box", "without_box")
_FAR = 1e6


@dataclass
class FrameEval:
    """One frame: true people (ids, [P, 2] m, cameras with a box of theirs) and estimates
    ([Q, 2] m, and per estimate the truth ids its boxes show and its camera count)."""

    truth_ids: np.ndarray
    truth_xy: np.ndarray
    truth_views: np.ndarray
    est_xy: np.ndarray
    est_people: list[set[int]] = field(default_factory=list)
    est_views: list[int] = field(default_factory=list)


def match(truth_xy: np.ndarray, est_xy: np.ndarray, gate_m: float) -> list[tuple[int, int]]:
    """Hungarian (truth row, estimate row) pairs within ``gate_m``."""
    if not len(truth_xy) or not len(est_xy):
        return []
    dist = np.linalg.norm(truth_xy[:, None] - est_xy[None], axis=2)
    cost = np.where(dist <= gate_m, dist, _FAR)
    rows, cols = linear_sum_assignment(cost)
    return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if cost[r, c] < _FAR]


def _percent(part: float, whole: float) -> float:
    return 100.0 * part / whole if whole else float("nan")


def score_frames(frames: Sequence[FrameEval], gate_m: float = GATE_M) -> dict:
    """Per-frame metrics, their split by camera count and the FP / FN attribution."""
    gt = tp = fp = 0
    errors: list[float] = []
    fp_kinds = dict.fromkeys(FP_KINDS, 0)
    fn_kinds = dict.fromkeys(FN_KINDS, 0)
    classes = [str(v) for v in range(MAX_CAMERAS_CLASS + 1)]
    gt_by = dict.fromkeys(classes, 0)
    tp_by = dict.fromkeys(classes, 0)
    err_by: dict[str, list[float]] = {c: [] for c in classes}
    est_by = dict.fromkeys(classes, 0)
    fp_by = dict.fromkeys(classes, 0)
    attributed = all(len(f.est_people) == len(f.est_xy) for f in frames)
    for f in frames:
        truth_xy = np.asarray(f.truth_xy, np.float64).reshape(-1, 2)
        est_xy = np.asarray(f.est_xy, np.float64).reshape(-1, 2)
        pairs = match(truth_xy, est_xy, gate_m)
        matched_truth = {r for r, _ in pairs}
        matched_est = {c for _, c in pairs}
        gt += len(truth_xy)
        tp += len(pairs)
        fp += len(est_xy) - len(pairs)
        views = [str(min(int(v), MAX_CAMERAS_CLASS)) for v in f.truth_views]
        for r, c in pairs:
            d = float(np.linalg.norm(truth_xy[r] - est_xy[c]))
            errors.append(d)
            tp_by[views[r]] += 1
            err_by[views[r]].append(d)
        for r in range(len(truth_xy)):
            gt_by[views[r]] += 1
            if r not in matched_truth:
                fn_kinds["with_box" if int(f.truth_views[r]) > 0 else "without_box"] += 1
        for c, v in enumerate(f.est_views):
            key = str(min(int(v), MAX_CAMERAS_CLASS))
            est_by[key] += 1
            fp_by[key] += c not in matched_est
        if attributed:
            matched_ids = {int(f.truth_ids[r]) for r in matched_truth}
            by_est = {c: int(f.truth_ids[r]) for r, c in pairs}
            for c in range(len(est_xy)):
                if c in matched_est:
                    continue
                people = f.est_people[c]
                if not people:
                    kind = "nobody"
                elif len(people) > 1:
                    kind = "mixed"
                elif next(iter(people)) in matched_ids - {by_est.get(c)}:
                    kind = "duplicate"
                else:
                    kind = "off"
                fp_kinds[kind] += 1
    fn = gt - tp
    result: dict = {
        "frames": len(frames),
        "gt": gt,
        "tp": tp,
        "fp": fp,
        "fn": fn,
        "precision": _percent(tp, tp + fp),
        "recall": _percent(tp, gt),
        "moda": 100.0 * (1.0 - (fp + fn) / gt) if gt else float("nan"),
        "modp": _percent(sum(1.0 - d / gate_m for d in errors), tp),
        "matched_mean_m": float(np.mean(errors)) if errors else float("nan"),
        "people_by_cameras": {c: _percent(gt_by[c], gt) / 100.0 for c in classes},
        "recall_by_cameras": {c: _percent(tp_by[c], gt_by[c]) for c in classes},
        "matched_mean_by_cameras": {
            c: float(np.mean(err_by[c])) if err_by[c] else float("nan") for c in classes
        },
        "estimates_by_cameras": est_by,
        "fp_by_cameras": fp_by,
        "fn_breakdown": fn_kinds,
    }
    if attributed:
        result["fp_breakdown"] = fp_kinds
    return result
