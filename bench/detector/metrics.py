"""Detector accuracy against hand-checked person boxes: matching, recall by height, edge errors.

Why our own few functions rather than a COCO toolkit: the product needs figures no toolkit
reports — recall per person *height* (a webcam in a 4–10 m room sees people 40–300 px tall and the
small ones decide whether the far half of the room works), and how far a found box's bottom and
top edges sit from the true foot and head top (the bottom edge is what puts a person on the
floor). The rules, decided once here:

- **Matching** (per frame, greedy by score, as PASCAL/COCO): detections in descending score each
  take the unmatched true box they overlap most, if that IoU ≥ the threshold. A true box marked
  ``ignore`` (too little visible to demand a detection) is never counted: a detection that lands
  on one (IoU ≥ threshold, or at least half of the detection inside it) is neither a hit nor a
  false positive.
- **Recall** is over true boxes not ignored, in height bins of the *true* box (pixels of the
  frame the detector saw). **Precision** = hits / (hits + false positives), over all frames.
- **Edge errors** of a matched box, as a fraction of the true box height ``h``:
  ``bottom = (det.ymax − true.ymax) / h`` (positive: the detector's bottom edge lies *below* the
  true foot), ``top = (det.ymin − true.ymin) / h`` (positive: the box starts *below* the head
  top, i.e. cuts the head). Only people neither occluded nor truncated count, because their true
  edges are seen, not estimated.

Example::

    truth = Truth.of([[10, 20, 40, 120]])
    match = match_frame(truth, np.array([[12, 25, 41, 118]]), np.array([0.9]), 0.5)
    match.found  # array([ True])
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

HEIGHT_BANDS: dict[str, tuple[float, float]] = {
    "<100": (0.0, 100.0),
    "100-200": (100.0, 200.0),
    ">200": (200.0, float("inf")),
    "80-300": (80.0, 300.0),  # the target band of issue 11
}


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of every box in ``a`` [N, 4] with every box in ``b`` [M, 4] (xmin, ymin, xmax, ymax)."""
    a = np.asarray(a, np.float64).reshape(-1, 4)
    b = np.asarray(b, np.float64).reshape(-1, 4)
    inter_w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    inter_h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = inter_w.clip(0) * inter_h.clip(0)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def inside_fraction(dets: np.ndarray, regions: np.ndarray) -> np.ndarray:
    """[M, R]: the fraction of each detection's area that lies inside each region box."""
    d = np.asarray(dets, np.float64).reshape(-1, 4)
    r = np.asarray(regions, np.float64).reshape(-1, 4)
    w = np.minimum(d[:, None, 2], r[None, :, 2]) - np.maximum(d[:, None, 0], r[None, :, 0])
    h = np.minimum(d[:, None, 3], r[None, :, 3]) - np.maximum(d[:, None, 1], r[None, :, 1])
    area = ((d[:, 2] - d[:, 0]) * (d[:, 3] - d[:, 1]))[:, None]
    return np.where(area > 0, w.clip(0) * h.clip(0) / np.where(area > 0, area, 1.0), 0.0)


@dataclass(frozen=True)
class Truth:
    """The true people of one frame: ``boxes`` [N, 4] and per-box flags [N] bool."""

    boxes: np.ndarray
    occluded: np.ndarray
    truncated: np.ndarray
    ignore: np.ndarray

    @staticmethod
    def of(
        boxes: Sequence[Sequence[float]] | np.ndarray,
        occluded: Sequence[bool] | None = None,
        truncated: Sequence[bool] | None = None,
        ignore: Sequence[bool] | None = None,
    ) -> Truth:
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        n = len(b)

        def flag(values: Sequence[bool] | None) -> np.ndarray:
            return np.zeros(n, bool) if values is None else np.asarray(values, bool).reshape(n)

        return Truth(b, flag(occluded), flag(truncated), flag(ignore))

    def scaled(self, factor: float) -> Truth:
        """The same people in a frame resized by ``factor`` (boxes scale, flags stay)."""
        return Truth(self.boxes * factor, self.occluded, self.truncated, self.ignore)

    @property
    def heights(self) -> np.ndarray:
        return self.boxes[:, 3] - self.boxes[:, 1]


@dataclass(frozen=True)
class FrameMatch:
    """Result of matching one frame: per true box the matched detection (-1: missed, or
    ignored), per detection ``"tp"``, ``"fp"`` or ``"ignored"``."""

    truth: Truth
    matched: np.ndarray  # [N] int
    status: np.ndarray  # [M] str

    @property
    def found(self) -> np.ndarray:
        return self.matched >= 0


def match_frame(
    truth: Truth, boxes: np.ndarray, scores: np.ndarray, iou_threshold: float
) -> FrameMatch:
    """Greedy score-ordered matching of detections to the true boxes of one frame."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    order = np.argsort(-np.asarray(scores, np.float64), kind="stable")
    iou = iou_matrix(boxes, truth.boxes)  # [M, N]
    inside = inside_fraction(boxes, truth.boxes)
    matched = np.full(len(truth.boxes), -1, np.int64)
    status = np.full(len(boxes), "fp", dtype=object)
    for d in order:
        candidates = np.flatnonzero(~truth.ignore & (matched < 0) & (iou[d] >= iou_threshold))
        if candidates.size:
            best = candidates[np.argmax(iou[d, candidates])]
            matched[best] = d
            status[d] = "tp"
        elif np.any(truth.ignore & ((iou[d] >= iou_threshold) | (inside[d] >= 0.5))):
            status[d] = "ignored"
    return FrameMatch(truth, matched, status.astype(str))


@dataclass(frozen=True)
class Evaluation:
    """Pooled per-person results over many frames at one score and IoU threshold.

    Arrays are over the true people that are not ignored: ``heights``, ``found``, flags, and
    the edge errors ``bottom``/``top`` (fractions of the true height, NaN when missed).
    """

    heights: np.ndarray
    found: np.ndarray
    occluded: np.ndarray
    truncated: np.ndarray
    bottom: np.ndarray
    top: np.ndarray
    true_positives: int
    false_positives: int
    frames: int

    @property
    def precision(self) -> float:
        total = self.true_positives + self.false_positives
        return self.true_positives / total if total else float("nan")

    @property
    def fp_per_frame(self) -> float:
        return self.false_positives / self.frames if self.frames else float("nan")

    def in_band(self, low: float, high: float) -> np.ndarray:
        """People whose true height h satisfies low ≤ h < high."""
        return (self.heights >= low) & (self.heights < high)

    def recall(self, low: float = 0.0, high: float = float("inf")) -> tuple[float, int]:
        """(recall, number of people) for true heights in [low, high)."""
        mask = self.in_band(low, high)
        n = int(mask.sum())
        return (float(self.found[mask].mean()) if n else float("nan")), n

    def recall_curve(self, edges: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """Recall and counts per bin ``[edges[i], edges[i+1])``."""
        recalls, counts = [], []
        for low, high in itertools.pairwise(edges):
            r, n = self.recall(low, high)
            recalls.append(r)
            counts.append(n)
        return np.array(recalls), np.array(counts)

    def edge_stats(
        self, edge: str, low: float = 0.0, high: float = float("inf")
    ) -> dict[str, float]:
        """Median |error|, median signed error (bias), mean signed, std and count of one edge
        (``"bottom"``/``"top"``) over found people fully in view with heights in [low, high)."""
        values = getattr(self, edge)
        mask = self.in_band(low, high) & self.found & ~self.occluded & ~self.truncated
        v = values[mask]
        if v.size == 0:
            nan = float("nan")
            return {"median_abs": nan, "bias": nan, "mean": nan, "std": nan, "n": 0}
        return {
            "median_abs": float(np.median(np.abs(v))),
            "bias": float(np.median(v)),
            "mean": float(np.mean(v)),
            "std": float(np.std(v)),
            "n": int(v.size),
        }


def evaluate(
    frames: Iterable[tuple[Truth, np.ndarray, np.ndarray]],
    score_threshold: float,
    iou_threshold: float,
) -> Evaluation:
    """Pool :func:`match_frame` over ``(truth, det_boxes, det_scores)`` triples; detections below
    ``score_threshold`` are dropped first (so one low-threshold run serves every threshold)."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("h", "f", "o", "t", "bot", "top")}
    tp = fp = count = 0
    for truth, boxes, scores in frames:
        count += 1
        boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
        scores = np.asarray(scores, np.float64).reshape(-1)
        keep = scores >= score_threshold
        match = match_frame(truth, boxes[keep], scores[keep], iou_threshold)
        tp += int((match.status == "tp").sum())
        fp += int((match.status == "fp").sum())
        use = ~truth.ignore
        heights = truth.heights
        bottom = np.full(len(heights), np.nan)
        top = np.full(len(heights), np.nan)
        hit = match.found
        det = boxes[keep][match.matched[hit]]
        bottom[hit] = (det[:, 3] - truth.boxes[hit, 3]) / heights[hit]
        top[hit] = (det[:, 1] - truth.boxes[hit, 1]) / heights[hit]
        for key, values in (
            ("h", heights),
            ("f", hit),
            ("o", truth.occluded),
            ("t", truth.truncated),
            ("bot", bottom),
            ("top", top),
        ):
            parts[key].append(values[use])

    def cat(key: str, dtype: type) -> np.ndarray:
        return np.concatenate(parts[key]).astype(dtype) if parts[key] else np.zeros(0, dtype)

    return Evaluation(
        heights=cat("h", float),
        found=cat("f", bool),
        occluded=cat("o", bool),
        truncated=cat("t", bool),
        bottom=cat("bot", float),
        top=cat("top", float),
        true_positives=tp,
        false_positives=fp,
        frames=count,
    )
