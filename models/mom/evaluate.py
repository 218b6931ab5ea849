"""Evaluate a trained model on a dataset file: the shared core of ``momloc eval`` and the benches.

Works with anything shaped like ``MomRuntime`` (``num_cameras``, ``observation``,
``localize(boxes, keypoints=None)``), so it needs no torch. Rows that no camera sees cannot be
localized by any method; they are left out and counted, never silently scored.

Example::

    runtime = MomRuntime.load("model/")
    result = evaluate(runtime, MomDataset.load("test.npz"))
    print(result.metrics["acc@0.3"], result.skipped)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.data.metrics import localization_metrics

BATCH = 4096  # rows per runtime call: bounds memory (D draws × K cameras × 12 estimators)


class Localizer(Protocol):
    num_cameras: int
    observation: str

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray: ...


@dataclass(frozen=True)
class Evaluation:
    """Metrics dict (:data:`models.data.metrics.METRIC_KEYS`), predictions [N, 2], evaluated
    rows."""

    metrics: dict[str, float]
    predictions: np.ndarray
    rows: np.ndarray
    skipped: int


def check_compatible(runtime: Localizer, data: MomDataset, name: str = "dataset") -> None:
    """Refuse a file the model cannot read: another camera count, or no keypoints for a
    keypoint model. One-line :class:`MomlocError`."""
    if data.num_cameras != runtime.num_cameras:
        raise MomlocError(
            f"{name}: {data.num_cameras} cameras but the model was trained for "
            f"{runtime.num_cameras}"
        )
    if runtime.observation == "keypoints" and data.keypoints is None:
        raise MomlocError(f"{name}: the model uses keypoints but the file has no 'keypoints' key")


def predict(runtime: Localizer, data: MomDataset, batch: int = BATCH) -> np.ndarray:
    """Floor positions [N, 2] for every row, in batches (results do not depend on batching)."""
    out = np.empty((data.n, 2), dtype=np.float64)
    for start in range(0, data.n, batch):
        rows = slice(start, start + batch)
        keypoints = None
        if runtime.observation == "keypoints" and data.keypoints is not None:
            keypoints = data.keypoints[rows]
        out[rows] = runtime.localize(data.boxes[rows], keypoints=keypoints)
    return out


def score(predictions: np.ndarray, data: MomDataset) -> Evaluation:
    """Metrics over the rows with a finite prediction and at least one camera view."""
    ok = np.isfinite(predictions).all(axis=1) & data.visible().any(axis=1)
    rows = np.flatnonzero(ok)
    if rows.size == 0:
        raise MomlocError("dataset: no row is seen by any camera, nothing to evaluate")
    metrics = localization_metrics(
        predictions[rows], data.world[rows, :2], data.frame[rows], data.track[rows]
    )
    return Evaluation(metrics, predictions, rows, int(data.n - rows.size))


def evaluate(runtime: Localizer, data: MomDataset, name: str = "dataset") -> Evaluation:
    """Check compatibility, localize every row, score."""
    check_compatible(runtime, data, name)
    return score(predict(runtime, data), data)
