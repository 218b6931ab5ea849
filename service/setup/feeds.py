"""Detection feeds for guided collection: live cameras, or a synthetic person who follows the plan.

The synthetic feed runs as fast as the simulator goes (simulated time, no sleeping), so an
unattended collection of 9 marks x 20 s takes seconds. It uses exactly the cameras of
``momloc simulate --preset NAME --seed S``, so a model trained on the collected marks can be
evaluated on a dense ``simulate`` file of the same scene.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np

from capture.worker import Frame
from common.errors import MomlocError
from models.simulate import get_config
from models.simulate.scene import Scene
from models.simulate.scripted import Segment, scripted_scene
from service.pipeline.live import Rig
from service.setup.collector import FeedFrame, Step
from service.stages import DetectStage, FrameSet


class SyntheticFeed:
    """Simulated detections of one scripted person walking the collection plan."""

    def __init__(self, preset: str, seed: int, detector_profile: str | None = None) -> None:
        self.config = get_config(preset, detector_profile=detector_profile)
        self.seed = seed
        self.image_sizes = np.array([c.image_size for c in self.config.cameras], np.int32)
        self.room = self.config.room
        self._fps = self.config.fps
        self.scene: Scene | None = None  # scripted by prepare()

    def prepare(self, steps: list[Step]) -> None:
        """Script the simulated person to follow ``steps`` back to back."""
        segments = [Segment(s.start, s.end, s.seconds) for s in steps]
        self.scene = scripted_scene(self.config, self.seed, segments)
        begins = np.concatenate([[0.0], np.cumsum([s.seconds for s in steps])])  # linear
        self._begins = {id(step): float(begins[i]) for i, step in enumerate(steps)}

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        scene = self.scene
        if scene is None:
            raise MomlocError("SyntheticFeed.frames: call prepare() with the plan first")
        begin = self._begins[id(step)]
        first = round(begin * self._fps)
        last = max(first + 1, round((begin + step.seconds) * self._fps))
        for index in range(first, last):
            observation = scene.observe(index)
            boxes: list[np.ndarray] = []
            keypoints: list[np.ndarray | None] = []
            for k in range(scene.num_cameras):
                found, points = observation.reported(k)  # false positives included
                boxes.append(found)
                keypoints.append(points)
            yield FeedFrame(index / self._fps, boxes, keypoints)

    def close(self) -> None:
        """Nothing to release: the scene lives in memory."""


class LiveFeed:
    """Live cameras and the configured detector: the very stages the daemon runs.

    Recording runs in real time: each step lasts ``step.seconds`` of wall clock, and every new
    frame set in that time is detected once (a slow detector skips frames, it never queues them).
    """

    def __init__(self, rig: Rig, detect: DetectStage, first_frame_timeout_s: float = 10.0) -> None:
        self.rig, self.detect = rig, detect
        rig.start()
        first = self._first_frame_set(first_frame_timeout_s)  # every camera's frame has an image
        images = [f.image for f in first.frames if f is not None and f.image is not None]
        self.image_sizes = np.array([[i.shape[1], i.shape[0]] for i in images], np.int32)

    @classmethod
    def from_config(cls, path: str) -> LiveFeed:
        from service.pipeline.build import build_detect_stage, build_rig
        from service.settings import load_settings

        settings = load_settings(path)
        rig, player = build_rig(settings)
        return cls(rig, build_detect_stage(settings, player))

    def _first_frame_set(self, timeout_s: float) -> FrameSet:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            frame_set = self.rig.frame_set()
            if frame_set is not None and all(_has_image(f) for f in frame_set.frames):
                return frame_set
            time.sleep(0.05)
        self.rig.stop()
        missing = (
            [] if frame_set is None else [k for k, f in enumerate(frame_set.frames) if f is None]
        )
        which = ", ".join(f"camera {k}" for k in missing) or "no camera"
        raise MomlocError(
            f"{which} delivered no frame within {timeout_s:g} s; check `momloc cameras`"
        )

    def prepare(self, steps: list[Step]) -> None:
        """Live people follow the printed instructions; nothing to script."""

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        end = time.monotonic() + step.seconds
        last = None
        while time.monotonic() < end:
            frame_set = self.rig.frame_set()
            stamp = None if frame_set is None else frame_set.timestamp
            if frame_set is None or stamp is None or stamp == last:
                time.sleep(0.005)
                continue
            last = stamp
            found = self.detect(frame_set)  # service.stages.DetectStage: Detections per camera
            keypoints = [d.keypoints for d in found] if self.detect.keypoints else None
            yield FeedFrame(stamp, [d.boxes for d in found], keypoints)

    def close(self) -> None:
        self.rig.stop()


def _has_image(frame: Frame | None) -> bool:
    return frame is not None and frame.image is not None
