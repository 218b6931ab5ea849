"""Served accuracy: a stream of tracked positions scored as a multi-object tracker is scored.

The per-frame metrics of :mod:`models.data.metrics` score one localizer call per person with the
true association. A client receives something else: the tracker's output, with ids, ghosts, misses,
smoothing and delay. This module scores that stream against ground truth, numpy + scipy only.

Matching (CLEAR MOT, as in py-motmetrics)
    Per frame, truth objects and served positions are matched one to one within ``gate_m``
    (0.5 m by default; 1 m is the lenient variant) on the floor distance. A truth object keeps
    the served id it was last matched to if that id is still within the gate (so a momentarily
    closer neighbour does not steal it and fake two switches); the rest are matched with the
    Hungarian algorithm (``scipy.optimize.linear_sum_assignment``), pairs beyond the gate never.
``tp``, ``fp``, ``fn``
    matched pairs; served positions left unmatched (ghosts, duplicates, a track far off);
    truth objects left unmatched (missed, not yet confirmed, too far off).
``id_switches``
    a truth object matched to a served id other than the one it was last matched to (at any
    earlier frame, so an id change across an occlusion counts too). An id change is counted
    once, when it happens, not on every following frame; two people swapping ids are two.
``precision``, ``recall``, ``mota``
    ``tp / (tp + fp)``, ``tp / (tp + fn)``, ``1 - (fn + fp + id_switches) / gt`` in percent.
``mean``, ``median``, ``acc@0.3``
    floor error of the matched pairs in metres (``acc@0.3``: percent strictly below 0.3 m);
    bounded by the gate, so read them together with recall.
``by_views``
    the same per number of cameras whose detector reports the person at that frame (``"0"``:
    seen by no detector, the track is coasting; ``"1"``, ``"2"``, ``"3+"``), with the recall of
    each class: single-view people are where the depth rests on one box.
``jitter_m``
    of a standing person: RMS over consecutive frames (same truth object, same served id, truth
    speed below ``still_speed_mps``) of ``|Δserved − Δtruth|``, the frame-to-frame shake a client
    sees while the person stands still. A constant offset gives zero: it is bias, not jitter.
``lag_s``
    of a walking person (truth speed above ``walk_speed_mps``): the time shift ``τ`` that best
    aligns the served positions with the truth trajectory, ``argmin_τ Σ |served(t) −
    truth(t − τ)|²`` over a 5 ms grid in ``[-0.5, 1.5]`` s (truth linearly interpolated, only
    samples whose shifted time stays inside the person's truth record for every ``τ``).
``along_track_lag_s``
    the least-squares ``τ`` in ``(served − truth) · v = −τ |v|²`` (truth velocity ``v``): the
    along-track error over the speed. It agrees with ``lag_s`` on straight walks; on turns the
    shift fit is the better-defined one, so ``lag_s`` is the headline.

Example::

    scorer = StreamScorer(gate_m=0.5)
    for t, truth_ids, truth_xy, views, ids, xy in stream:
        scorer.add(t, truth_ids, truth_xy, ids, xy, views)
    print(scorer.result()["mota"])
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from common.errors import MomlocError

VIEW_CLASSES = ("0", "1", "2", "3+")
STILL_SPEED_MPS = 0.05  # the walkers of models.simulate stand at exactly 0 m/s when paused
WALK_SPEED_MPS = 0.5  # they cruise at 0.8-1.5 m/s
LAG_GRID_S = np.round(np.arange(-0.5, 1.5 + 1e-9, 0.005), 3)
_FAR = 1e6


@dataclass
class _Match:
    frame: int
    t: float
    truth: int
    served: int
    xy: np.ndarray  # served [2]
    truth_xy: np.ndarray  # [2]
    views: int  # -1: unknown


def view_class(views: int) -> str:
    """``"0"``, ``"1"``, ``"2"`` or ``"3+"`` for a camera count."""
    return VIEW_CLASSES[min(max(int(views), 0), 3)]


class StreamScorer:
    """Accumulates frames of a served stream and its truth; :meth:`result` gives the metrics."""

    def __init__(
        self,
        gate_m: float = 0.5,
        *,
        still_speed_mps: float = STILL_SPEED_MPS,
        walk_speed_mps: float = WALK_SPEED_MPS,
    ) -> None:
        if gate_m <= 0:
            raise MomlocError(f"stream metrics: gate {gate_m} m must be positive")
        self.gate_m = float(gate_m)
        self.still_speed_mps = float(still_speed_mps)
        self.walk_speed_mps = float(walk_speed_mps)
        self._last: dict[int, int] = {}  # truth id -> served id it was last matched to
        self._frames = self._gt = self._tp = self._fp = self._switches = 0
        self._gt_views: dict[str, int] = dict.fromkeys(VIEW_CLASSES, 0)
        self._matches: list[_Match] = []
        self._truth: dict[int, list[tuple[float, float, float]]] = {}  # id -> (t, x, y)
        self._time: float | None = None

    def add(
        self,
        t: float,
        truth_ids: Sequence[int] | np.ndarray,
        truth_xy: np.ndarray,
        served_ids: Sequence[int] | np.ndarray,
        served_xy: np.ndarray,
        views: Sequence[int] | np.ndarray | None = None,
    ) -> list[tuple[int, int]]:
        """One frame at time ``t`` (seconds, increasing): the people who should be served
        (ids, [P, 2] metres, optionally how many cameras' detectors report each) and what was
        served (ids, [Q, 2] metres). Returns the frame's matches as (truth row, served row)
        pairs, for diagnostics that attribute the misses (``bench/serving/stream_breakdown.py``)."""
        truth_ids = [int(i) for i in np.asarray(truth_ids).reshape(-1)]
        served_ids = [int(i) for i in np.asarray(served_ids).reshape(-1)]
        truth_xy = np.asarray(truth_xy, dtype=np.float64).reshape(-1, 2)
        served_xy = np.asarray(served_xy, dtype=np.float64).reshape(-1, 2)
        view_counts = [-1] * len(truth_ids) if views is None else [int(v) for v in views]
        if len(truth_xy) != len(truth_ids) or len(view_counts) != len(truth_ids):
            raise MomlocError("stream metrics: truth ids, positions and views differ in length")
        if len(served_xy) != len(served_ids):
            raise MomlocError("stream metrics: served ids and positions differ in length")
        if len(set(truth_ids)) != len(truth_ids) or len(set(served_ids)) != len(served_ids):
            raise MomlocError("stream metrics: an id appears twice in one frame")
        if self._time is not None and t <= self._time:
            raise MomlocError(f"stream metrics: time {t} does not follow {self._time}")
        if not (np.isfinite(truth_xy).all() and np.isfinite(served_xy).all()):
            raise MomlocError("stream metrics: positions must be finite")
        self._time = float(t)

        pairs = self._match(truth_ids, truth_xy, served_ids, served_xy)
        for r, c in pairs:
            o, h = truth_ids[r], served_ids[c]
            if o in self._last and self._last[o] != h:
                self._switches += 1
            self._last[o] = h
            self._matches.append(
                _Match(self._frames, float(t), o, h, served_xy[c], truth_xy[r], view_counts[r])
            )
        for o, xy in zip(truth_ids, truth_xy, strict=True):
            self._truth.setdefault(o, []).append((float(t), float(xy[0]), float(xy[1])))
        for v in view_counts:
            if v >= 0:
                self._gt_views[view_class(v)] += 1
        self._frames += 1
        self._gt += len(truth_ids)
        self._tp += len(pairs)
        self._fp += len(served_ids) - len(pairs)
        return pairs

    def _match(
        self,
        truth_ids: Sequence[int],
        truth_xy: np.ndarray,
        served_ids: Sequence[int],
        served_xy: np.ndarray,
    ) -> list[tuple[int, int]]:
        if not len(truth_ids) or not len(served_ids):
            return []
        dist = np.linalg.norm(truth_xy[:, None] - served_xy[None], axis=2)
        column = {h: c for c, h in enumerate(served_ids)}
        kept = []
        for r, o in enumerate(truth_ids):  # last correspondences still within the gate stay
            c = column.get(self._last.get(o, -1))
            if c is not None and dist[r, c] <= self.gate_m:
                kept.append((r, c))
        rows = [r for r in range(len(truth_ids)) if r not in {r for r, _ in kept}]
        cols = [c for c in range(len(served_ids)) if c not in {c for _, c in kept}]
        if rows and cols:
            sub = dist[np.ix_(rows, cols)]
            cost = np.where(sub <= self.gate_m, sub, _FAR)
            for i, j in zip(*linear_sum_assignment(cost), strict=True):
                if cost[i, j] < _FAR:
                    kept.append((rows[i], cols[j]))
        return kept

    # ------------------------------------------------------------------------------- results

    def result(self) -> dict:
        """All metrics (see the module docstring); plain floats and ints, JSON-ready."""
        errors = np.array([np.linalg.norm(m.xy - m.truth_xy) for m in self._matches])
        fn = self._gt - self._tp
        out: dict = {
            "gate_m": self.gate_m,
            "frames": self._frames,
            "gt": self._gt,
            "tp": self._tp,
            "fp": self._fp,
            "fn": fn,
            "id_switches": self._switches,
            "precision": _percent(self._tp, self._tp + self._fp),
            "recall": _percent(self._tp, self._gt),
            "mota": 100.0 * (1.0 - (fn + self._fp + self._switches) / self._gt)
            if self._gt
            else float("nan"),
            **_error_stats(errors),
        }
        views = np.array([m.views for m in self._matches], dtype=np.int64)
        if self._gt_views and sum(self._gt_views.values()):
            split = {}
            for name in VIEW_CLASSES:
                mask = np.array([view_class(v) == name for v in views], dtype=bool) & (views >= 0)
                split[name] = {
                    "gt": self._gt_views[name],
                    "recall": _percent(int(mask.sum()), self._gt_views[name]),
                    **_error_stats(errors[mask] if len(errors) else errors),
                }
            out["by_views"] = split
        out.update(self._jitter())
        out.update(self._lag())
        return out

    def _trajectories(self) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per truth id: times [T], positions [T, 2], velocities [T, 2] (finite differences)."""
        out = {}
        for o, rows in self._truth.items():
            a = np.array(rows)
            t, xy = a[:, 0], a[:, 1:]
            v = np.gradient(xy, t, axis=0) if len(t) > 1 else np.zeros_like(xy)
            out[o] = (t, xy, v)
        return out

    def _jitter(self) -> dict:
        by_truth: dict[int, list[_Match]] = {}
        for m in self._matches:
            by_truth.setdefault(m.truth, []).append(m)
        squares = []
        for ms in by_truth.values():
            for a, b in itertools.pairwise(ms):
                if b.frame != a.frame + 1 or b.served != a.served:
                    continue
                moved = b.truth_xy - a.truth_xy
                if np.linalg.norm(moved) / (b.t - a.t) >= self.still_speed_mps:
                    continue
                squares.append(float(np.sum((b.xy - a.xy - moved) ** 2)))
        return {
            "jitter_m": float(np.sqrt(np.mean(squares))) if squares else float("nan"),
            "jitter_n": len(squares),
        }

    def _lag(self) -> dict:
        none = {"lag_s": float("nan"), "along_track_lag_s": float("nan"), "lag_n": 0}
        if not self._matches:
            return none
        trajectories = self._trajectories()
        lo, hi = float(LAG_GRID_S.min()), float(LAG_GRID_S.max())
        sse = np.zeros(len(LAG_GRID_S))
        along_num = along_den = 0.0
        n = 0
        for o, (t, xy, v) in trajectories.items():
            ms = [m for m in self._matches if m.truth == o]
            if not ms:
                continue
            ts = np.array([m.t for m in ms])
            served = np.stack([m.xy for m in ms])
            speed_now = np.linalg.norm(np.stack([np.interp(ts, t, v[:, i]) for i in (0, 1)], 1), 1)
            walk = (speed_now > self.walk_speed_mps) & (ts - hi >= t[0]) & (ts - lo <= t[-1])
            if not walk.any():
                continue
            ts, served = ts[walk], served[walk]
            shifted = ts[None, :] - LAG_GRID_S[:, None]  # [G, S]
            gx = np.interp(shifted, t, xy[:, 0])
            gy = np.interp(shifted, t, xy[:, 1])
            sse += ((served[None, :, 0] - gx) ** 2 + (served[None, :, 1] - gy) ** 2).sum(axis=1)
            vel = np.stack([np.interp(ts, t, v[:, i]) for i in (0, 1)], axis=1)
            truth_now = np.stack([np.interp(ts, t, xy[:, i]) for i in (0, 1)], axis=1)
            along_num += float(((served - truth_now) * vel).sum())
            along_den += float((vel**2).sum())
            n += len(ts)
        if not n:
            return none
        return {
            "lag_s": _parabolic_min(LAG_GRID_S, sse),
            "along_track_lag_s": -along_num / along_den,
            "lag_n": n,
        }


def _parabolic_min(grid: np.ndarray, values: np.ndarray) -> float:
    """Argmin of ``values`` on ``grid``, refined by a parabola through its neighbours."""
    i = int(np.argmin(values))
    if 0 < i < len(grid) - 1:
        a, b, c = values[i - 1 : i + 2]
        curvature = a - 2 * b + c
        if curvature > 0:
            return float(grid[i] + 0.5 * (a - c) / curvature * (grid[1] - grid[0]))
    return float(grid[i])


def _percent(part: int, whole: int) -> float:
    return 100.0 * part / whole if whole else float("nan")


def _error_stats(errors: np.ndarray) -> dict:
    if not len(errors):
        return {"n": 0, "mean": float("nan"), "median": float("nan"), "acc@0.3": float("nan")}
    return {
        "n": len(errors),
        "mean": float(errors.mean()),
        "median": float(np.median(errors)),
        "acc@0.3": float(100.0 * np.mean(errors < 0.3)),
    }


@dataclass(frozen=True)
class StreamFrame:
    """One frame of a scored stream (see :meth:`StreamScorer.add` for the fields)."""

    t: float
    truth_ids: np.ndarray
    truth_xy: np.ndarray
    served_ids: np.ndarray
    served_xy: np.ndarray
    views: np.ndarray | None = None


def score_stream(frames: Sequence[StreamFrame], gate_m: float = 0.5, **options: float) -> dict:
    """:class:`StreamScorer` over a whole stream at once."""
    scorer = StreamScorer(gate_m, **options)
    for f in frames:
        scorer.add(f.t, f.truth_ids, f.truth_xy, f.served_ids, f.served_xy, f.views)
    return scorer.result()
