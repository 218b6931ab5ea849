"""Detections replay ("momloc detections v1"): a detector's raw output, every box of every camera.

Why a second file format beside MoM dataset v1: a dataset row is a *person* (boxes already
grouped across cameras, each with a true floor position), so it cannot hold what a detector
really returns: boxes of people nobody labelled, of people outside the set-up area, false boxes.
Serving has to cope with all of them, so a replay of the raw output is what ``momloc track
--detections`` needs to measure the chain as it serves. Written by ``momloc import``.

===============  ====================  =======================================================
key              dtype, shape          meaning
===============  ====================  =======================================================
format           str scalar            ``"momloc detections v1"``
frame            int64 [M]             frame index of each box (frames need not be contiguous)
camera           int64 [M]             camera index 0..K-1
boxes            float32 [M, 4]        xmin, ymin, xmax, ymax in pixels (finite, max >= min)
scores           float32 [M]           detector confidence (1 where the source gave none)
image_size       int32 [K, 2]          width, height of each camera's images
fps              float64 scalar        frame rate of the frame index (frame / fps = seconds)
===============  ====================  =======================================================

Rows keep the source order within a (frame, camera), which is the order the stage hands them to
the association (:class:`ReplayDetections` does not shuffle: the rows carry no identity).

Example::

    replay = DetectionsReplay.load("cmc2.npz")
    boxes, scores = replay.at(frame=12, camera=0)
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.atomic import atomic_write
from common.errors import MomlocError
from models.data.dataset import MAX_CAMERAS, read_npz

FORMAT = "momloc detections v1"
KEYS = ("format", "frame", "camera", "boxes", "scores", "image_size", "fps")


@dataclass(frozen=True)
class DetectionsReplay:
    """A validated replay held in memory (see the module docstring for the fields)."""

    frame: np.ndarray
    camera: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    image_size: np.ndarray
    fps: float

    def __post_init__(self) -> None:
        m = len(self.frame)
        arrays: dict[str, np.ndarray] = {
            "frame": np.asarray(self.frame, np.int64).reshape(-1),
            "camera": np.asarray(self.camera, np.int64).reshape(-1),
            "boxes": np.asarray(self.boxes, np.float32).reshape(-1, 4),
            "scores": np.asarray(self.scores, np.float32).reshape(-1),
            "image_size": np.asarray(self.image_size, np.int32),
        }
        for key in ("camera", "boxes", "scores"):
            if len(arrays[key]) != m:
                raise MomlocError(f"key '{key}': {len(arrays[key])} rows but 'frame' has {m}")
        size = arrays["image_size"]
        if size.ndim != 2 or size.shape[1] != 2 or not 1 <= len(size) <= MAX_CAMERAS:
            raise MomlocError(f"key 'image_size': shape {size.shape} is not [K, 2], K in 1..9")
        if (size <= 0).any():
            raise MomlocError("key 'image_size': width and height must be positive")
        if ((arrays["camera"] < 0) | (arrays["camera"] >= len(size))).any():
            raise MomlocError(f"key 'camera': an index outside 0..{len(size) - 1}")
        boxes = arrays["boxes"]
        if not np.isfinite(boxes).all():
            raise MomlocError("key 'boxes': contains NaN or infinite values")
        if ((boxes[:, 2] < boxes[:, 0]) | (boxes[:, 3] < boxes[:, 1])).any():
            raise MomlocError("key 'boxes': a box has xmax < xmin or ymax < ymin")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise MomlocError(f"key 'fps': {self.fps} is not a positive frame rate")
        for key, value in arrays.items():
            object.__setattr__(self, key, value)
        object.__setattr__(self, "fps", float(self.fps))
        order = np.lexsort((arrays["camera"], arrays["frame"]))  # stable: source order kept
        keys = arrays["frame"][order] * len(size) + arrays["camera"][order]
        starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]]) if m else np.zeros(0, int)
        ends = [*starts[1:], m]
        object.__setattr__(
            self, "_index", {int(keys[s]): order[s:e] for s, e in zip(starts, ends, strict=True)}
        )

    @property
    def num_cameras(self) -> int:
        return len(self.image_size)

    @property
    def n(self) -> int:
        return len(self.frame)

    def rows(self, frame: int, camera: int) -> np.ndarray:
        """Indices of the boxes of ``camera`` at ``frame``, in source order."""
        index: dict[int, np.ndarray] = self._index  # type: ignore[attr-defined]
        return index.get(int(frame) * self.num_cameras + int(camera), np.zeros(0, np.int64))

    def at(self, frame: int, camera: int) -> tuple[np.ndarray, np.ndarray]:
        """Boxes [M, 4] and scores [M] of ``camera`` at ``frame``."""
        rows = self.rows(frame, camera)
        return self.boxes[rows], self.scores[rows]

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write atomically (:mod:`common.atomic`)."""
        arrays = {
            "format": np.array(FORMAT),
            "frame": self.frame,
            "camera": self.camera,
            "boxes": self.boxes,
            "scores": self.scores,
            "image_size": self.image_size,
            "fps": np.array(self.fps, np.float64),
        }

        def produce(tmp: Path) -> None:
            with open(tmp, "wb") as handle:
                np.savez_compressed(handle, allow_pickle=False, **arrays)

        return atomic_write(path, produce)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> DetectionsReplay:
        """Read and validate; every problem raises :class:`MomlocError` naming file and key."""
        arrays = read_npz(path)
        if str(arrays.get("format", "")) != FORMAT:
            raise MomlocError(f"{path}: key 'format': not '{FORMAT}'")
        missing = [k for k in KEYS if k not in arrays]
        if missing:
            raise MomlocError(f"{path}: key '{missing[0]}': missing")
        try:
            return cls(
                arrays["frame"],
                arrays["camera"],
                arrays["boxes"],
                arrays["scores"],
                arrays["image_size"],
                float(arrays["fps"]),
            )
        except (MomlocError, ValueError, TypeError) as error:
            raise MomlocError(f"{path}: {error}") from None


def is_replay(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a detections replay (else: a dataset v1 file, or an error later)."""
    try:
        with np.load(path, allow_pickle=False) as archive:
            return "format" in archive.files and str(archive["format"]) == FORMAT
    except (zipfile.BadZipFile, OSError, EOFError, ValueError):
        return False
