"""Per-frame detection scores on the floor (CLEAR MOD), as the multi-view detection papers report
them, so our figures sit next to theirs (MVDet's MODA 83.9 % on MultiviewX, for one).

Per frame, served positions and true positions are matched one to one with the Hungarian
algorithm on floor distance, pairs beyond ``gate_m`` (0.5 m) never. Over all frames:
``MODA = 1 - (FP + FN) / GT`` and ``MODP = mean(1 - d / gate)`` over the matched pairs (MVDet's
evaluation), precision ``TP / (TP + FP)``, recall ``TP / GT``, and the matched pairs' mean
distance in metres. Tracking (ids) is scored elsewhere (:mod:`models.data.stream_metrics`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

GATE_M = 0.5


def match_floor(
    served: np.ndarray, truth: np.ndarray, gate_m: float = GATE_M
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hungarian matching within ``gate_m``: (served index [M], truth index [M], distance [M])."""
    served = np.asarray(served, float).reshape(-1, 2)
    truth = np.asarray(truth, float).reshape(-1, 2)
    if not len(served) or not len(truth):
        empty = np.zeros(0, np.int64)
        return empty, empty, np.zeros(0)
    dist = np.linalg.norm(served[:, None] - truth[None], axis=2)
    rows, cols = linear_sum_assignment(np.where(dist <= gate_m, dist, 1e6))
    keep = dist[rows, cols] <= gate_m
    return rows[keep], cols[keep], dist[rows[keep], cols[keep]]


@dataclass
class DetectionScore:
    """CLEAR MOD counts over frames (see the module docstring)."""

    gate_m: float = GATE_M
    tp: int = 0
    fp: int = 0
    fn: int = 0
    distances: list[float] = field(default_factory=list)

    def add(self, served: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Score one frame; returns the matched served and truth indices."""
        served = np.asarray(served, float).reshape(-1, 2)
        truth = np.asarray(truth, float).reshape(-1, 2)
        rows, matched, dist = match_floor(served, truth, self.gate_m)
        self.tp += len(matched)
        self.fp += len(served) - len(matched)
        self.fn += len(truth) - len(matched)
        self.distances.extend(dist.tolist())
        return rows, matched

    @property
    def gt(self) -> int:
        return self.tp + self.fn

    def result(self) -> dict[str, float]:
        """``moda``, ``modp``, ``precision``, ``recall`` in percent, ``mean`` metres, counts."""
        d = np.asarray(self.distances, float)
        nan = float("nan")
        return {
            "moda": 100.0 * (1.0 - (self.fp + self.fn) / self.gt) if self.gt else nan,
            "modp": 100.0 * float(np.mean(1.0 - d / self.gate_m)) if d.size else nan,
            "precision": 100.0 * self.tp / (self.tp + self.fp) if self.tp + self.fp else nan,
            "recall": 100.0 * self.tp / self.gt if self.gt else nan,
            "mean": float(d.mean()) if d.size else nan,
            "tp": float(self.tp),
            "fp": float(self.fp),
            "fn": float(self.fn),
            "gt": float(self.gt),
        }
