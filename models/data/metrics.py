"""Localization metrics of the paper's Table 1, defined precisely once.

The paper names the metrics but not their formulas; these are the definitions used everywhere in
this project (``momloc eval``, the benchmarks), with ``e_i = ||pred_i - truth_i||`` the Euclidean
floor error of row ``i`` in metres:

``mean``, ``median``, ``std``
    of ``e_i`` over all rows (``std`` is the population standard deviation, ddof = 0).
``acc@t`` for t in 0.2, 0.3, 0.4, 0.5 m
    percentage of rows with ``e_i < t`` (strictly less, as in the paper: "less than 0.2 m").
``ate`` (absolute trajectory error)
    TUM-style ATE *without* alignment: the predictions and the truth already share the floor
    frame of the marks, so a similarity alignment would hide real errors. Per track it is the RMSE
    of the position error over the track's trajectory; tracks are pooled weighted by their length,
    i.e. ``ate = sqrt(sum_tracks sum_i e_i^2 / N)``: every trajectory point counts once.
``rpe`` (relative pose error)
    TUM-style RPE of the translation over one frame step: within each track (rows sorted by
    ``frame``), for every pair of rows whose frames differ by exactly ``delta``, the error of the
    relative displacement ``||(p_j - p_i) - (g_j - g_i)||``; ``rpe`` is the RMSE over all such
    pairs. ``delta`` defaults to the data's frame step: the smallest positive frame difference
    between consecutive rows of any track (1 for consecutive video frames). Pairs across a gap
    (the person unseen for a while) are skipped, so an occlusion does not count as a jump. NaN
    when no pair exists (every track a single row).

Example::

    m = localization_metrics(pred, data.world[:, :2], data.frame, data.track)
    print(m["mean"], m["acc@0.3"])
"""

from __future__ import annotations

import math

import numpy as np

from common.errors import MomlocError

THRESHOLDS = (0.2, 0.3, 0.4, 0.5)
METRIC_KEYS = ("n", "mean", "median", "std", "ate", "rpe", *(f"acc@{t}" for t in THRESHOLDS))


def _check(pred: np.ndarray, truth: np.ndarray, frame: np.ndarray, track: np.ndarray) -> None:
    if pred.ndim != 2 or pred.shape[1] != 2:
        raise MomlocError(f"predictions: shape {pred.shape} is not [N, 2]")
    if truth.shape != pred.shape:
        raise MomlocError(f"ground truth: shape {truth.shape} does not match {pred.shape}")
    n = pred.shape[0]
    if n == 0:
        raise MomlocError("metrics: no rows to evaluate")
    if frame.shape != (n,) or track.shape != (n,):
        raise MomlocError(f"frame/track: shapes {frame.shape}, {track.shape} are not [{n}]")
    if not np.isfinite(pred).all():
        raise MomlocError("predictions: contain NaN or infinite values")


def frame_step(frame: np.ndarray, track: np.ndarray) -> int | None:
    """Smallest positive frame difference between consecutive rows of a track (None if none)."""
    order = np.lexsort((frame, track))
    same = track[order][1:] == track[order][:-1]
    steps = np.diff(frame[order])[same]
    steps = steps[steps > 0]
    return int(steps.min()) if steps.size else None


def relative_errors(
    pred: np.ndarray,
    truth: np.ndarray,
    frame: np.ndarray,
    track: np.ndarray,
    delta: int | None = None,
) -> np.ndarray:
    """Per pair relative-displacement errors [M] (metres) for pairs ``delta`` frames apart."""
    if delta is None:
        delta = frame_step(frame, track)
        if delta is None:
            return np.zeros(0)
    order = np.lexsort((frame, track))
    p, g, f, t = pred[order], truth[order], frame[order], track[order]
    pair = (t[1:] == t[:-1]) & (f[1:] - f[:-1] == delta)
    moved_pred = p[1:][pair] - p[:-1][pair]
    moved_true = g[1:][pair] - g[:-1][pair]
    return np.linalg.norm(moved_pred - moved_true, axis=1)


def localization_metrics(
    pred: np.ndarray,
    truth: np.ndarray,
    frame: np.ndarray,
    track: np.ndarray,
    *,
    delta: int | None = None,
) -> dict[str, float]:
    """All Table-1 metrics as a dict with exactly :data:`METRIC_KEYS` (see module docstring).

    ``pred`` and ``truth`` are [N, 2] floor positions in metres (a [N, 3] truth is cut to x, y),
    ``frame`` and ``track`` [N] integers. Values are plain floats (``n`` an int) so the dict
    serialises to JSON directly; ``rpe`` is NaN when no pair of rows is ``delta`` frames apart.
    """
    pred = np.asarray(pred, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)[:, :2]
    frame = np.asarray(frame, dtype=np.int64)
    track = np.asarray(track, dtype=np.int64)
    _check(pred, truth, frame, track)
    err = np.linalg.norm(pred - truth, axis=1)
    rel = relative_errors(pred, truth, frame, track, delta)
    out: dict[str, float] = {
        "n": int(err.size),
        "mean": float(err.mean()),
        "median": float(np.median(err)),
        "std": float(err.std()),
        "ate": float(np.sqrt(np.mean(err**2))),
        "rpe": float(np.sqrt(np.mean(rel**2))) if rel.size else math.nan,
    }
    for t in THRESHOLDS:
        out[f"acc@{t}"] = float(100.0 * np.mean(err < t))
    return out


_LABELS = {
    "n": "Rows",
    "mean": "Mean",
    "median": "Median",
    "std": "Std",
    "ate": "ATE",
    "rpe": "RPE",
}


def format_table(metrics: dict[str, float]) -> str:
    """A two-column, human-readable table of a metrics dict (errors in m, accuracies in %)."""
    lines = []
    for key in METRIC_KEYS:
        value = metrics[key]
        if key == "n":
            text = f"{int(value)}"
        elif key.startswith("acc@"):
            text = f"{value:.2f} %"
        else:
            text = "n/a" if math.isnan(value) else f"{value:.3f} m"
        label = f"Acc@{key[4:]} m" if key.startswith("acc@") else _LABELS[key]
        lines.append(f"{label:<12}{text:>12}")
    return "\n".join(lines)
