"""``momloc track``: the live chain on recorded data, as fast as the CPU allows.

One :class:`~service.pipeline.live.Pipeline` (the daemon's class, built as ``service.daemon`` builds
it: detector stage, association, MoM model, tracker with the settings' ``tracking`` options) is fed
frame set by frame set through ``Pipeline.process``; no rig, no thread, no pacing. Tracking and
every time-based rule read the frames' capture times, so a recording tracks as it would have
live, only faster. The detector runs inline on every frame set (``detection.schedule:
every_frame``): the live scheduler detects when the CPU is free, which offline would make the
result depend on the machine's load. The camera-shift check runs inline too (deterministic).

Two feeds, both a sequence of ``(frame index, FrameSet)`` plus the detection stage to use:

- :func:`recording_feed`: a ``momloc record`` folder through the configured real detector.
- :func:`detections_feed`: a dataset v1 file's boxes as the detector's output, one frame set per
  frame index from the first to the last frame (frames nobody was seen in are empty sets, so the
  tracker ages its tracks as it would live), stamped ``frame / fps``. Each camera's boxes are
  shuffled with a seeded generator, so neither row order nor track ids tell the association who
  is who. Keypoints are not fed: the pipeline's detection contract carries boxes only today
  (issue 13, "a keypoint model cannot be served"); they join once it carries them.
  A *detections replay* (``models.data.detections_replay``, written by ``momloc import``) is fed the
  same way, every box of every camera as recorded (boxes of nobody included, source order: its
  rows carry no identity to hide), at the replay's own fps unless one is given.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from capture.recording import Recording
from capture.rig import FrameSet
from capture.worker import CameraState, Frame
from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.data.detections_replay import DetectionsReplay, is_replay
from models.detector.base import Detections
from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from service.settings import Settings
from service.snapshot import Snapshot
from service.stages import DetectStage, LocalizationModel, Unscheduled
from service.tracking.smoother import FixedLagSmoother

if TYPE_CHECKING:  # imported where used (scoring reads the simulator's truth tables)
    from service.offline.track_output import TruthScore


@dataclass
class Feed:
    """Frame sets to track, how many, their cameras' image sizes, and the detection stage."""

    frame_sets: Iterator[tuple[int, FrameSet]]
    total: int
    image_sizes: list[tuple[int, int]]
    detect: DetectStage
    origin: str

    @property
    def num_cameras(self) -> int:
        return len(self.image_sizes)


def recording_feed(recording: Recording, settings: Settings) -> Feed:
    """A recording through the detector of ``settings`` (scheduled inline, see above)."""
    from service.pipeline.build import build_detect_stage

    inline = settings.detection.model_copy(update={"schedule": "every_frame"})
    detect = build_detect_stage(settings.model_copy(update={"detection": inline}), None)
    sets, sizes = recording.frame_sets(), recording.image_sizes
    return Feed(sets, len(recording), sizes, detect, str(recording.folder))


class DatasetDetections(Unscheduled):
    """Detection stage answering each frame set with a dataset's boxes (and, if it has them,
    keypoints) of that frame index, as a detector would: one ``Detections`` per camera."""

    def __init__(self, data: MomDataset, seed: int = 0) -> None:
        self.data = data
        self.keypoints = data.keypoints is not None  # what a keypoint model needs (Pipeline)
        self.rng = np.random.default_rng([seed, 13])
        order = np.argsort(data.frame, kind="stable")
        frames = data.frame[order]
        starts = np.searchsorted(frames, np.unique(frames))
        self._rows = {
            int(frames[s]): order[s:e]
            for s, e in zip(starts, [*starts[1:], len(frames)], strict=True)
        }

    def __call__(self, frame_set: FrameSet) -> list[Detections]:
        seq = next((f.seq for f in frame_set.frames if f is not None), None)
        empty = np.zeros(0, np.int64)
        rows = self._rows.get(int(seq), empty) if seq is not None else empty
        out = []
        for k in range(self.data.num_cameras):
            boxes = self.data.boxes[rows, k].reshape(-1, 4)
            seen = np.isfinite(boxes).all(axis=1)
            shuffle = self.rng.permutation(int(seen.sum()))
            points = None
            if self.data.keypoints is not None:
                points = self.data.keypoints[rows, k][seen][shuffle].astype(np.float32)
            out.append(
                Detections(
                    boxes[seen][shuffle].astype(np.float32),
                    np.ones(len(shuffle), np.float32),
                    points,
                )
            )
        return out


class ReplayDetections(Unscheduled):
    """Detection stage answering each frame set with a replay's boxes of that frame index."""

    keypoints = False

    def __init__(self, replay: DetectionsReplay) -> None:
        self.replay = replay

    def __call__(self, frame_set: FrameSet) -> list[Detections]:
        seq = next((f.seq for f in frame_set.frames if f is not None), None)
        out = []
        for k, f in enumerate(frame_set.frames):
            if f is None or seq is None:
                out.append(Detections.empty())
                continue
            boxes, scores = self.replay.at(int(seq), k)
            out.append(Detections(boxes.copy(), scores.copy(), None))
        return out


def detections_feed(path: str | Path, fps: float | None, seed: int = 0) -> Feed:
    """A dataset v1 file's or a detections replay's boxes as detector output (see the module
    docstring); ``fps`` None: the replay's own, 15 (the simulator's) for a dataset."""
    detect: DatasetDetections | ReplayDetections
    if is_replay(path):
        replay = DetectionsReplay.load(path)
        fps = replay.fps if fps is None else fps
        frames, sizes_array, detect = replay.frame, replay.image_size, ReplayDetections(replay)
        if not len(frames):
            raise MomlocError(f"{path}: the replay has no boxes")
    else:
        data = MomDataset.load(path)
        fps = 15.0 if fps is None else fps
        frames, sizes_array, detect = data.frame, data.image_size, DatasetDetections(data, seed)
    if not fps > 0:
        raise MomlocError(f"--fps {fps:g}: must be positive")
    first, last = int(frames.min()), int(frames.max())
    sizes = [(int(w), int(h)) for w, h in sizes_array]

    def frame_sets() -> Iterator[tuple[int, FrameSet]]:
        for f in range(first, last + 1):
            frames: list[Frame | None] = [
                Frame(camera=k, image=None, timestamp=f / fps, seq=f) for k in range(len(sizes))
            ]
            yield f, FrameSet(frames=frames, skew=0.0, stale=[False] * len(sizes))

    return Feed(frame_sets(), last - first + 1, sizes, detect, str(path))


class _NoRig:
    """The pipeline is driven by ``process``: nothing to start, no frames to wait for."""

    def start(self) -> None: ...

    def stop(self) -> None: ...

    def frame_set(self, after: FrameSet | None = None, timeout: float = 0.0) -> None:
        return None

    def states(self) -> list[CameraState]:
        return []


def check_model(runtime: LocalizationModel, feed: Feed, model_dir: Path) -> None:
    """Refuse a model that cannot localise these cameras (one line, before any work)."""
    if int(runtime.num_cameras) != feed.num_cameras:
        raise MomlocError(
            f"{model_dir}: model expects {runtime.num_cameras} cameras, "
            f"{feed.origin} has {feed.num_cameras}"
        )
    for k, (expected, got) in enumerate(
        zip(np.asarray(runtime.image_sizes).tolist(), feed.image_sizes, strict=True)
    ):
        if got != (0, 0) and tuple(int(v) for v in expected) != tuple(got):
            raise MomlocError(
                f"{model_dir}: model expects {expected[0]}x{expected[1]} images from camera {k}, "
                f"{feed.origin} has {got[0]}x{got[1]}"
            )


def offline_pipeline(
    settings: Settings, runtime: LocalizationModel, feed: Feed, model_dir: Path
) -> Pipeline:
    """The daemon's pipeline for ``feed`` (mirrors ``service.daemon.build_daemon``)."""
    from service.pipeline.build import build_tracker

    check_model(runtime, feed, model_dir)
    return Pipeline(
        _NoRig(),
        feed.detect,
        Hub(),
        num_cameras=feed.num_cameras,
        runtime=runtime,
        model_dir=model_dir,
        tracker=build_tracker(settings),
        max_error_px=settings.tracking.max_error_px,
        outside_area=settings.tracking.outside_area,
        shift_threaded=False,
    )


def offline_settings(config: Path | None, cameras: Sequence[str]) -> Settings:
    """Detector and tracking options from ``config`` (or defaults), cameras from the data."""
    from service.settings import load_settings

    return load_settings(config, cameras=[{"type": "file", "path": c} for c in cameras])


@dataclass(frozen=True)
class TrackSummary:
    frame_sets: int
    seconds: float
    positions: int
    ids: int

    @property
    def rate(self) -> float:
        return self.frame_sets / self.seconds if self.seconds > 0 else float("nan")


def run_track(
    pipeline: Pipeline,
    feed: Feed,
    out: Path,
    *,
    as_csv: bool = False,
    score: TruthScore | None = None,
    progress: bool = True,
    smooth_s: float = 0.0,
) -> TrackSummary:
    """Process every frame set of ``feed``, writing ``out`` atomically (nothing on failure).

    ``smooth_s`` > 0: each snapshot is written (and scored) once the frames ``smooth_s`` after
    it are tracked, its positions fitted over ``± smooth_s`` (:mod:`service.tracking.smoother`); 0
    writes what the live pipeline would have served.
    """
    import time

    from tqdm import tqdm

    from common.atomic import atomic_write
    from service.offline.track_output import PositionWriter

    counts: dict[str, Any] = {}
    start = time.perf_counter()
    smoother = FixedLagSmoother(smooth_s) if smooth_s > 0 else None

    def produce(tmp: Path) -> None:
        with open(tmp, "w", newline="") as handle:
            writer = PositionWriter(handle, as_csv)

            def emit(ready: list[tuple[int, Snapshot]]) -> None:
                for frame, snapshot in ready:
                    writer.write(frame, snapshot)
                    if score is not None:
                        score.add(frame, snapshot)
                counts.update(positions=writer.positions, ids=len(writer.ids))

            sets = tqdm(
                feed.frame_sets, total=feed.total, unit="set", desc="tracking", disable=not progress
            )
            for n, (frame, frame_set) in enumerate(sets, start=1):
                snapshot = pipeline.process(frame_set)
                emit([(frame, snapshot)] if smoother is None else smoother.push(frame, snapshot))
                counts.update(sets=n)
            if smoother is not None:
                emit(smoother.flush())

    try:
        atomic_write(out, produce)
    finally:
        pipeline.stop()
    return TrackSummary(
        counts.get("sets", 0),
        time.perf_counter() - start,
        counts.get("positions", 0),
        counts.get("ids", 0),
    )
