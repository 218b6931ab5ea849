"""The check step offline: what the daemon serves at a recording's floor marks, scored as the
live check scores it (``momloc eval --served``).

The recording's boxes go frame by frame through the daemon's association and tracking
(:func:`service.offline.track.offline_pipeline`, no smoothing: what the live map shows), and
each row at a mark is scored by :mod:`service.setup.check_score`: the distance from the mark to
the nearest served person that frame, the median per mark, the median over marks.

Why a second figure beside the per-row ``momloc eval``: the check measures served positions,
and a recording's rows are not all served. Measured on the synthetic 3x3 set-up (nanodet
profile, 20 s per mark, checked at four marks, 5 s each): per row, eval gave a median 0.62 m,
because at mark A1 one camera's only box was a lasting false positive (4.4 m off) and at C3 a
camera reported the person in 2 of 38 frames beside a false box; the tracker serves neither
(nobody at A1, as the live check saw). Scored as served, the same recording gave 0.11, 0.12,
0.66 m and nobody at A1, where the live check gave 0.08, 0.12, 0.65 m and nobody at A1.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

from common.errors import MomlocError
from models.data.dataset import MomDataset
from service.offline import track as offline
from service.setup.check_score import mark_error, nearest_error, summarise
from service.setup.collector import mark_key, mark_names

MIN_MARK_ROWS = 5  # a floor position held this many rows is a mark (a walk's labels move on)


def served_at_marks(model_dir: Path, data_path: Path, *, fps: float = 15.0) -> dict[str, Any]:
    """The check's summary (:func:`service.setup.check_score.summarise`) of what the daemon
    serves on the recording ``data_path`` with the model in ``model_dir``."""
    from models.mom.runtime import MomRuntime

    data = MomDataset.load(data_path)
    keys = [mark_key(float(x), float(y)) for x, y in data.world[:, :2]]
    counts: dict[tuple[int, int], int] = defaultdict(int)
    for key in keys:
        counts[key] += 1
    first_row = {key: row for row, key in reversed(list(enumerate(keys)))}
    marks = [key for key in dict.fromkeys(keys) if counts[key] >= MIN_MARK_ROWS]
    if not marks:
        raise MomlocError(
            f"{data_path}: no floor mark (no position held {MIN_MARK_ROWS} rows): --served "
            "scores mark recordings; use momloc track --truth for walks"
        )
    rows_of_frame: dict[int, list[int]] = defaultdict(list)
    for row, frame in enumerate(data.frame):
        rows_of_frame[int(frame)].append(row)
    runtime = MomRuntime.load(model_dir)
    feed = offline.detections_feed(data_path, fps)
    settings = offline.offline_settings(None, [str(data_path)] * feed.num_cameras)
    pipeline = offline.offline_pipeline(settings, runtime, feed, model_dir)
    errors: dict[tuple[int, int], list[float]] = defaultdict(list)
    try:
        for frame, frame_set in feed.frame_sets:
            people = pipeline.process(frame_set).people
            for row in rows_of_frame.get(frame, []):
                x, y = (float(v) for v in data.world[row, :2])
                error = nearest_error(people, x, y)
                if counts[keys[row]] >= MIN_MARK_ROWS and error is not None:
                    errors[keys[row]].append(error)
    finally:
        pipeline.stop()
    names = mark_names(data_path)
    per_mark = []
    for key in marks:
        x, y = (float(v) for v in data.world[first_row[key], :2])
        per_mark.append(
            {
                "name": names.get(key, f"{x:.2f},{y:.2f}"),
                "x": x,
                "y": y,
                "error_m": mark_error(errors[key]),
                "samples": len(errors[key]),
                "rows": counts[key],
            }
        )
    summary = summarise(per_mark)
    del summary["time"]
    return summary
