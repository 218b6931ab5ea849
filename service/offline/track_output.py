"""What ``momloc track`` writes and scores: positions per frame set, served accuracy vs truth.

Positions: JSON lines, one per frame set, the snapshot the daemon would have published
(``service.pipeline.hub.Snapshot.as_dict``: ``v, seq, t, people``) plus ``frame`` (the frame set's
index in the recording, or the dataset's frame index); or CSV with one row per person per frame set
(``t, frame, id, x, y, vx, vy, cameras``, cameras as space-separated indices), for spreadsheets.

Served accuracy: :class:`TruthScore` feeds :class:`models.data.stream_metrics.StreamScorer` (the
same metrics ``bench/serving/stream_accuracy.py`` reports) at the gates of
``service.offline.stream_eval``. The truth of frame ``f`` is the dataset's rows with ``frame == f``:
for ``momloc simulate``, the people the simulated detector reports in at least one camera (the
simulator writes no row for a person no camera sees). Its views are the cameras with a box in that
row. The scorer's clock is the snapshot time, nudged by 1 µs where two frame sets share the capture
time of their oldest frame.
"""

from __future__ import annotations

import csv
import json
import math
from typing import Any, TextIO

import numpy as np

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.data.stream_metrics import StreamScorer
from service.offline.stream_eval import GATES
from service.snapshot import Snapshot

CSV_HEADER = ["t", "frame", "id", "x", "y", "vx", "vy", "cameras"]


class PositionWriter:
    """Writes snapshots to an open text file as JSON lines or CSV."""

    def __init__(self, handle: TextIO, as_csv: bool = False) -> None:
        self.handle, self.as_csv = handle, as_csv
        self.positions = 0
        self.ids: set[int] = set()
        self._csv = csv.writer(handle) if as_csv else None
        if self._csv is not None:
            self._csv.writerow(CSV_HEADER)

    def write(self, frame: int, snapshot: Snapshot) -> None:
        self.positions += len(snapshot.people)
        self.ids |= {int(p["id"]) for p in snapshot.people}
        if self._csv is None:
            row = {**snapshot.as_dict(), "frame": frame}
            self.handle.write(json.dumps(row, separators=(",", ":")) + "\n")
            return
        for p in snapshot.people:
            cameras = " ".join(str(k) for k in p["cameras"])
            fields = (p["id"], p["x"], p["y"], p["vx"], p["vy"])
            self._csv.writerow([f"{snapshot.t:.6f}", frame, *fields, cameras])


class TruthScore:
    """Scores each frame set's snapshot against a dataset v1 file of the same frames."""

    def __init__(self, truth: MomDataset, num_cameras: int, total_frames: int) -> None:
        if truth.num_cameras != num_cameras:
            raise MomlocError(
                f"--truth: the file has {truth.num_cameras} cameras, the tracked data {num_cameras}"
            )
        self.truth = truth
        self.total_frames = total_frames
        self.scorers = {float(g): StreamScorer(g) for g in GATES}
        self._by_frame: dict[int, list[int]] = {}
        for row, f in enumerate(truth.frame.tolist()):
            self._by_frame.setdefault(int(f), []).append(row)
        self._time: float | None = None
        self.scored = 0

    def add(self, frame: int, snapshot: Snapshot) -> None:
        rows = np.asarray(self._by_frame.get(frame, []), np.int64)
        t = float(snapshot.t)
        if self._time is not None and t <= self._time:
            t = self._time + 1e-6
        self._time = t
        ids = self.truth.track[rows]
        xy = self.truth.world[rows, :2]
        views = np.isfinite(self.truth.boxes[rows]).all(axis=2).sum(axis=1)
        served_ids = [int(p["id"]) for p in snapshot.people]
        served_xy = np.array([[p["x"], p["y"]] for p in snapshot.people]).reshape(-1, 2)
        for scorer in self.scorers.values():
            scorer.add(t, ids, xy, served_ids, served_xy, views)
        self.scored += int(frame in self._by_frame)

    def result(self) -> dict[str, Any]:
        """Metrics at the 0.5 m gate at the top level, every gate under ``gates``."""
        if not self.scored:
            frames = self.truth.frame
            raise MomlocError(
                f"--truth: its frames {int(frames.min())}..{int(frames.max())} are none of the "
                f"{self.total_frames} tracked frame sets' indices"
            )
        by_gate = {f"{g:g}": _finite(s.result()) for g, s in self.scorers.items()}
        return {**by_gate[f"{GATES[0]:g}"], "gates": by_gate}


def _finite(value: Any) -> Any:
    """NaN (a metric with nothing to measure) as null: strict JSON has no NaN."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, float) and math.isnan(value):
        return None
    return value


def format_scores(result: dict[str, Any]) -> str:
    """Readable lines, one per gate."""
    lines = []
    for gate, r in result["gates"].items():

        def num(key: str, digits: int, unit: str = "", r: dict = r) -> str:
            value = r.get(key)
            return "n/a" if value is None else f"{value:.{digits}f}{unit}"

        lines.append(
            f"served accuracy at {gate} m: precision {num('precision', 1, ' %')}, recall "
            f"{num('recall', 1, ' %')}, MOTA {num('mota', 1, ' %')}, id switches "
            f"{r['id_switches']}, error mean {num('mean', 3, ' m')} median "
            f"{num('median', 3, ' m')}, acc@0.3 {num('acc@0.3', 1, ' %')}, standing jitter "
            f"{num('jitter_m', 3, ' m')}"
        )
    return "\n".join(lines)
