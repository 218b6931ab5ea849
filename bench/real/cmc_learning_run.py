"""A CMC replay served by the daemon's pipeline with the daemon's learning room attached.

What :mod:`bench.real.cmc_self_learning` drives: the same ``Pipeline.process`` as
``bench.real.cmc_chain.serve``, with the listeners ``service.daemon.build_learning`` hangs off
it: the self-label collector (:class:`service.learning.listener.SelfLabeler`, rules from the
daemon's default ``learning`` settings, inline so a run is deterministic) and, for a bumped
camera, the self-healing job (:class:`service.learning.healer.Healer`), which hot-loads its
repair through ``Pipeline.reload_model``. The collector is told a camera moved when the
pipeline's own camera-moved check raises it (as in the daemon) or, from ``alert_frame`` on,
regardless (``forced``: CMC has no images for the image check, and the reprojection check
alone may take long on 4 fps): the frame the real check raised it is reported separately.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from models.data.detections_replay import DetectionsReplay
from models.mom.runtime import MomRuntime
from service.learning.healer import Healer
from service.learning.labels import LabelRules
from service.learning.listener import SelfLabeler
from service.offline import track as offline
from service.pipeline.live import Pipeline

GAP_FRAMES = 40  # 10 s without boxes between two chained sequences: every track ends


def chained(parts: list[DetectionsReplay]) -> tuple[DetectionsReplay, list[int]]:
    """The replays one after another (each shifted past the last frame of the one before by
    ``GAP_FRAMES``), and each part's frame offset."""
    offsets, frames, start = [], [], 0
    for part in parts:
        offset = start - int(part.frame.min())
        offsets.append(offset)
        frames.append(part.frame + offset)
        start = int(frames[-1].max()) + GAP_FRAMES
    first = parts[0]
    return (
        DetectionsReplay(
            np.concatenate(frames),
            np.concatenate([p.camera for p in parts]),
            np.concatenate([p.boxes for p in parts]),
            np.concatenate([p.scores for p in parts]),
            first.image_size,
            first.fps,
        ),
        offsets,
    )


@dataclass
class LearningRun:
    """The pipeline after the run (its ``runtime`` is the model in service at the end), the
    collector, the healer (None without a bump) and, for a bump, the frames of the real
    check's alert and of the repaired model going into service (None: never)."""

    pipeline: Pipeline
    labeler: SelfLabeler
    healer: Healer | None
    check_frame: int | None
    repaired_frame: int | None


def serve_learning(
    model_dir: Path,
    replay: Path,
    data_dir: Path,
    *,
    bumped: int | None = None,
    alert_frame: int = 0,
    min_separation_m: float | None = None,
) -> LearningRun:
    """Serve ``replay`` with the model of ``model_dir``, collecting self-labels into
    ``data_dir`` (and, ``bumped`` a camera, healing it from ``alert_frame``; the run ends at
    the repair). ``min_separation_m``: that setting instead of the daemon's default. Call
    ``pipeline.stop()`` when done with the result."""
    runtime = MomRuntime.load(model_dir)
    feed = offline.detections_feed(replay, None)
    settings = offline.offline_settings(None, [str(replay)] * feed.num_cameras)
    pipeline = offline.offline_pipeline(settings, runtime, feed, model_dir)
    learning = settings.learning
    forced: set[int] = set()

    def checked() -> set[int]:
        return {c.camera for c in pipeline.alignment_status() if c.moved}

    labeler = SelfLabeler(
        data_dir,
        rules=LabelRules(
            min_views=learning.min_views,
            max_std_m=learning.max_std_m,
            max_cost=learning.max_cost,
            min_separation_m=learning.min_separation_m
            if min_separation_m is None
            else min_separation_m,
            min_interval_s=learning.min_interval_s,
        ),
        moved=lambda: checked() | forced,
        max_bytes=int(learning.max_mb * 1e6),
        threaded=False,
    )
    healer = None
    if bumped is not None:
        healer = Healer(data_dir, labeler, pipeline, min_positions=learning.heal_min_positions)
        labeler.followers.append(healer)
    pipeline.add_listener(labeler)
    check_frame = repaired_frame = None
    for frame, frame_set in feed.frame_sets:
        if bumped is not None and frame >= alert_frame:
            forced.add(bumped)
        pipeline.process(frame_set)
        if bumped is None or frame < alert_frame:
            continue
        if check_frame is None and bumped in checked():
            check_frame = frame
        assert healer is not None
        if any(s.state == "repaired" for s in healer.done):
            repaired_frame = frame
            break
    labeler.close()
    return LearningRun(pipeline, labeler, healer, check_frame, repaired_frame)
