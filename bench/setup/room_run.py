"""A simulated room served by the daemon's chain, with the learning room's listener attached.

What the self-learning bench (:mod:`bench.setup.self_learning`) drives: the scene's detector
reports (:func:`service.offline.stream_eval.frame_detections`) go through the one
:class:`~service.pipeline.chain.Chain` in scene time, and each frame set's
:class:`~service.stages.FrameResult` goes to the same listeners the daemon hangs off its
pipeline: the self-label collector (inline, so a run is deterministic) and, when the scene bumps
a camera, the camera-moved checks (reprojection error; the image check on frames drawn once a
second). A model swap goes through :meth:`RoomRun.reload_model`, as ``Pipeline.reload_model`` does.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from capture.rig import FrameSet
from capture.worker import Frame
from models.mom.runtime import MomRuntime
from models.simulate import Scene, SceneConfig
from service.learning.listener import SelfLabeler
from service.offline.stream_eval import frame_detections
from service.pipeline.chain import Chain
from service.pipeline.listeners import CameraWatch
from service.snapshot import Snapshot
from service.stages import FrameResult
from service.tracking.tracker import RECOMMENDED, Tracker


class RoomRun:
    """One scene walked frame by frame (``advance``), the model in service swappable."""

    def __init__(
        self,
        config: SceneConfig,
        seed: int,
        runtime: MomRuntime,
        data_dir: Path,
        *,
        watch: bool = False,
        listeners: tuple[Callable[[FrameResult], None], ...] = (),
    ) -> None:
        self.scene = Scene(config, seed=seed)
        self.runtime: MomRuntime = runtime
        self.model_dir: Path = runtime.model_dir
        self.chain = Chain(Tracker(fps_hint=self.scene.fps, **RECOMMENDED))
        self.rng = np.random.default_rng([seed, 77])
        self.k = int(runtime.num_cameras)
        self.watch = CameraWatch(self.k, shift_threaded=False) if watch else None
        self.labeler = SelfLabeler(data_dir, threaded=False, moved=self.moved)
        self.listeners = listeners
        self.frame = 0

    def moved(self) -> set[int]:
        return set() if self.watch is None else {c.camera for c in self.watch.status() if c.moved}

    def reload_model(self, model_dir: str | Path | None = None) -> dict[str, Any]:
        """Swap the model in service (what ``Pipeline.reload_model`` does)."""
        self.model_dir = self.model_dir if model_dir is None else Path(model_dir)
        self.runtime = MomRuntime.load(self.model_dir)
        self.chain.new_model()
        return {"path": str(model_dir)}

    def advance(self, frames: int) -> None:
        for _ in range(frames):
            self.step()

    def step(self) -> FrameResult:
        i = self.frame
        self.frame += 1
        obs = self.scene.observe(i)
        t = i / self.scene.fps
        detections = frame_detections(obs, self.rng)
        associations, tracks = self.chain(t, detections, self.runtime, [True] * self.k, i + 1)
        images: list[Frame | None] = [None] * self.k
        if self.watch is not None and self.watch.camera_shift.due(t):
            images = [Frame(k, self.scene.render(i, k), t, i) for k in range(self.k)]
        result = FrameResult(
            frame_set=FrameSet(frames=images, skew=0.0),
            t_capture=t,
            fused=[True] * self.k,
            detections=detections,
            associations=associations,
            tracks=tracks,
            snapshot=Snapshot.build(i + 1, t, []),
            runtime=self.runtime,
            timings_ms={},
            outside=self.chain.outside,
        )
        if self.watch is not None:
            self.watch(result)
        self.labeler(result)
        for listener in self.listeners:
            listener(result)
        return result
