"""Frames with textured boxes moving at constant velocity, and a detector that finds them.

Shared by the box-carrier and detection-schedule tests: the images are real pixels (so optical
flow has something to follow), the detector returns each frame's true box exactly and records
which frames it was given. :class:`FunctionStage` and :class:`NoRig` are the pipeline tests'
doubles of a detection stage and a rig (``service.stages.DetectStage``,
``service.pipeline.live.Rig``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from capture.rig import FrameSet
from capture.worker import CameraState, Frame
from models.detector.base import Detections, PersonDetector
from service.stages import Unscheduled

FPS = 30.0


def moving_box(i: int, camera: int = 0, start=(100.0, 120.0), velocity=(4.0, 1.0)) -> np.ndarray:
    """xmin, ymin, xmax, ymax of the box in frame ``i`` (pixels; moves ``velocity`` px/frame)."""
    x = start[0] + 40 * camera + velocity[0] * i
    y = start[1] + velocity[1] * i
    return np.array([x, y, x + 60, y + 180], np.float32)


_TEXTURE = (np.random.default_rng(0).random((180, 60)) * 255).astype(np.uint8)
_BACKGROUND = (np.random.default_rng(1).random((480, 640)) * 60 + 60).astype(np.uint8)


def draw(boxes: Sequence[np.ndarray]) -> np.ndarray:
    """A 640x480 BGR frame: noisy background, one textured 60x180 patch per box."""
    grey = _BACKGROUND.copy()
    for box in boxes:
        x0, y0 = round(float(box[0])), round(float(box[1]))
        grey[y0 : y0 + 180, x0 : x0 + 60] = _TEXTURE
    return np.repeat(grey[:, :, None], 3, axis=2)


class BoxWorld:
    """Frame sets of ``cameras`` cameras, each showing one moving box."""

    def __init__(self, cameras: int = 2, velocity=(4.0, 1.0)) -> None:
        self.cameras, self.velocity = cameras, velocity
        self.truth: dict[int, tuple[int, int]] = {}  # id(image) -> (frame, camera)
        self._images: list[np.ndarray] = []  # keeps ids unique while the test runs

    def box(self, i: int, camera: int) -> np.ndarray:
        return moving_box(i, camera, velocity=self.velocity)

    def frame_set(self, i: int) -> FrameSet:
        frames: list[Frame | None] = []
        for k in range(self.cameras):
            image = draw([self.box(i, k)])
            self.truth[id(image)] = (i, k)
            self._images.append(image)
            frames.append(Frame(camera=k, image=image, timestamp=i / FPS, seq=i))
        return FrameSet(frames=frames, skew=0.0)


class FakeDetector(PersonDetector):
    """Finds each frame's true box; ``calls`` lists the (frame, camera) pairs of every call."""

    kind = "fake"

    def __init__(self, world: BoxWorld, gone_from: int | None = None) -> None:
        self.world, self.gone_from = world, gone_from  # finds nobody from frame ``gone_from`` on
        self.calls: list[list[tuple[int, int]]] = []

    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        seen = [self.world.truth[id(image)] for image in frames]
        self.calls.append(seen)
        return [
            Detections.empty()
            if self.gone_from is not None and i >= self.gone_from
            else Detections(self.world.box(i, k)[None], np.array([0.9], np.float32))
            for i, k in seen
        ]


class Clock:
    """A clock the test moves by hand."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def frames_at(
    seq: int, stamp: float, present: Sequence[bool], image: np.ndarray | None = None
) -> FrameSet:
    """One frame set: a frame numbered ``seq`` at ``stamp`` for each camera ``present``."""
    frames = [
        Frame(camera=k, image=image, timestamp=stamp, seq=seq) if on else None
        for k, on in enumerate(present)
    ]
    return FrameSet(frames=frames, skew=0.0)


class FunctionStage(Unscheduled):
    """A detection stage made of a function of the frame set (no schedule, no thread)."""

    def __init__(
        self, detect: Callable[[FrameSet], list[Detections]], keypoints: bool = False
    ) -> None:
        self.detect = detect
        self.keypoints = keypoints

    def __call__(self, frame_set: FrameSet) -> list[Detections]:
        return self.detect(frame_set)


class NoRig:
    """A rig for pipelines driven by ``Pipeline.process`` alone: it never has a frame set."""

    def start(self) -> None: ...
    def stop(self) -> None: ...

    def frame_set(self, after: FrameSet | None = None, timeout: float = 0.0) -> FrameSet | None:
        return None

    def states(self) -> list[CameraState]:
        return []
