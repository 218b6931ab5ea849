"""The daemon's own pipeline over a real data set's frames, fed by a per-frame detection report
(``momloc track`` offline: :mod:`service.offline.track`), scored two ways in one run:

- its tracks, as ``momloc track --truth`` scores them
  (:class:`service.offline.track_output.TruthScore`: MOTA, id switches, Acc@0.3, jitter of standing
  people);
- per frame, the positions of its associations before tracking against every annotated person
  (:class:`bench.real.scoring.DetectionScore`, MODA/MODP), read by a pipeline listener, so the
  association runs once per frame set for both.

Frames are stamped ``frame / fps``, so tracking runs at the data's real rate.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.real.scoring import DetectionScore
from capture.rig import FrameSet
from models.data.dataset import MomDataset
from models.detector.base import Detections
from models.mom.runtime import MomRuntime
from service.stages import Unscheduled


def _frame_index(frame_set: FrameSet) -> int:
    return int(next(f.seq for f in frame_set.frames if f is not None))


class ReportStage(Unscheduled):
    """Detection stage answering each frame set with ``report(frame index)`` (no schedule, no
    worker thread: :class:`~service.stages.Unscheduled`)."""

    keypoints = False

    def __init__(self, report: Callable[[int], list[Detections]]) -> None:
        self.report = report

    def __call__(self, frame_set: FrameSet) -> list[Detections]:
        return self.report(_frame_index(frame_set))


def stream_chain(
    frames: Sequence[int],
    fps: float,
    report: Callable[[int], list[Detections]],
    annotated: Callable[[int], np.ndarray],
    runtime: MomRuntime,
    model_dir: Path,
    truth: MomDataset,
) -> tuple[dict[str, Any], dict[str, float]]:
    """Tracks scored on ``truth`` (dataset v1 rows of the people to serve) and per-frame
    association positions scored on ``annotated(frame)`` [P, 2] (see the module docstring)."""
    from capture.worker import Frame
    from service.offline import track as offline
    from service.offline.track_output import TruthScore
    from service.stages import FrameResult

    sizes = [(int(w), int(h)) for w, h in truth.image_size]

    def sets() -> Iterator[tuple[int, FrameSet]]:
        for f in frames:
            cams: list[Frame | None] = [
                Frame(camera=k, image=None, timestamp=f / fps, seq=f) for k in range(len(sizes))
            ]
            yield f, FrameSet(frames=cams, skew=0.0, stale=[False] * len(sizes))

    feed = offline.Feed(sets(), len(frames), sizes, ReportStage(report), "real data")
    settings = offline.offline_settings(None, ["real data"] * len(sizes))
    pipeline = offline.offline_pipeline(settings, runtime, feed, model_dir)
    score = TruthScore(truth, len(sizes), len(frames))
    detection = DetectionScore()

    def per_frame(result: FrameResult) -> None:
        served = np.array([a.world for a in result.associations], float).reshape(-1, 2)
        detection.add(served, annotated(_frame_index(result.frame_set)))

    pipeline.add_listener(per_frame)
    offline.run_track(pipeline, feed, model_dir / "track.jsonl", score=score, progress=False)
    return score.result(), detection.result()
