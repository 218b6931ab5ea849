"""Hand-made frame results for the self-label tests: people, their boxes and tracks."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from capture.rig import FrameSet
from models.detector.base import Detections
from service.snapshot import Snapshot
from service.stages import Association, FrameResult, Track
from tests.service.mom_doubles import ModelDouble

SIZES = np.array([[640, 480], [640, 480]], np.int32)


@dataclass
class FakeModel(ModelDouble):
    """What the labeler reads from a model: its image sizes and ``model.json``."""

    meta: dict[str, Any] = field(default_factory=lambda: {"num_cameras": 2, "id": 1})
    num_cameras: int = 2
    image_sizes: np.ndarray = field(default_factory=lambda: SIZES.copy())

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        return np.full((len(boxes), 2), np.nan)

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        return np.full(len(boxes), np.nan)


@dataclass
class Person:
    x: float
    y: float
    boxes: list[list[float] | None]  # per camera, None: unseen
    std_m: float = 0.05
    cost: float = 10.0
    coasting: bool = False
    track: int = 1


def frame_result(
    people: list[Person],
    t: float = 100.0,
    seq: int = 5,
    model: Any = None,
    beyond: list[Person] = (),  # type: ignore[assignment]
) -> FrameResult:
    """One frame set where each person is an association and a track measured now, and each
    of ``beyond`` an untracked association beyond the set-up area."""
    cameras = 2
    per_camera: list[list[list[float]]] = [[] for _ in range(cameras)]
    associations, tracks = [], []
    for i, p in enumerate([*people, *beyond]):
        index: list[int | None] = []
        for k in range(cameras):
            box = p.boxes[k]
            if box is None:
                index.append(None)
            else:
                index.append(len(per_camera[k]))
                per_camera[k].append(box)
        boxes = np.array([b if b is not None else [np.nan] * 4 for b in p.boxes], np.float32)
        associations.append(
            Association(
                boxes=boxes,
                cameras=[k for k in range(cameras) if p.boxes[k] is not None],
                world=np.array([p.x, p.y]),
                cost=p.cost,
                detection_index=index,
                covariance=np.eye(2) * p.std_m**2,
            )
        )
        if i >= len(people):
            associations[-1].inside = False
            continue
        frame = seq if not p.coasting else seq - 3
        track = Track(p.track, p.x, p.y, 0, 0, 1.0, [], p.coasting, 2.0, frame, association=i)
        tracks.append(track)
    detections = [
        Detections(
            np.array(b, np.float32).reshape(-1, 4),
            np.ones(len(b), np.float32),
            np.zeros((len(b), 17, 3), np.float32),
        )
        for b in per_camera
    ]
    return FrameResult(
        frame_set=FrameSet(frames=[None, None], skew=0.0),
        t_capture=t,
        fused=[True, True],
        detections=detections,
        associations=associations[: len(people)],
        tracks=tracks,
        snapshot=Snapshot.build(seq, t, []),
        runtime=FakeModel() if model is None else model,
        timings_ms={},
        outside=associations[len(people) :],
    )
