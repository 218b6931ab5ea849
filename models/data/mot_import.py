"""Your own recordings in: per-camera MOTChallenge detections + a positions file -> dataset, replay.

Input formats (``momloc import``; text, one record per line, fields separated by commas or
whitespace, blank lines and lines starting with ``#`` skipped):

MOTChallenge detections, one file per camera, given in camera order
    ``frame, id, bb_left, bb_top, bb_width, bb_height, conf[, x, y, z]`` (pixels; the trailing
    world columns of MOT are ignored). ``id`` -1 means "no identity" (raw detector output);
    ``conf`` -1 (MOT's "not given") or a missing column becomes 1.
Positions
    ``frame, id, x, y`` with x, y the floor position of person ``id`` at ``frame`` in metres,
    in the floor frame the model is to serve (the marks' frame). One line per person and frame.

Outputs
    - a **detections replay** (``models.data.detections_replay``): every box of every camera, ids
      ignored, so ``momloc track --detections`` serves exactly what the detector returned;
    - a **MoM dataset v1** (training or truth) when the MOT rows carry ids: one row per
      (frame, id) of the positions file whose id has a box in at least one camera that frame
      (a row without any box teaches nothing and the simulator writes none either); boxes from
      the MOT rows with that frame and id, NaN where a camera has none. Rows with id -1 (boxes
      of nobody) stay out of the dataset and in the replay.

Why the ids must come from the user's own pairing: this module never guesses who a box belongs
to; a calibration-free product has no geometry to do it with.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.data.detections_replay import DetectionsReplay

MOT_FIELDS = ("frame", "id", "bb_left", "bb_top", "bb_width", "bb_height", "conf")
POSITION_FIELDS = ("frame", "id", "x", "y")


@dataclass(frozen=True)
class MotBoxes:
    """One camera's MOT file: frame [M], id [M] (-1: none), boxes [M, 4] xyxy, scores [M]."""

    frame: np.ndarray
    id: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray

    @property
    def has_ids(self) -> bool:
        """Whether any row names a person (rows with id -1 are boxes of nobody)."""
        return bool((self.id >= 0).any())


@dataclass(frozen=True)
class Positions:
    """frame [N], id [N], world [N, 2] metres."""

    frame: np.ndarray
    id: np.ndarray
    world: np.ndarray


def _records(path: Path, names: Sequence[str], required: int) -> list[tuple[int, list[float]]]:
    """(line number, numbers) per record; the first bad field raises naming file:line:field."""
    if not path.is_file():
        raise MomlocError(f"{path}: no such file")
    out = []
    with open(path, encoding="utf-8", errors="replace") as handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            parts = text.replace(",", " ").split()
            if len(parts) < required:
                field = names[len(parts)]
                raise MomlocError(f"{path}:{number}: field '{field}' missing")
            values = []
            for i, part in enumerate(parts[: len(names)]):
                try:
                    value = float(part)
                except ValueError:
                    raise MomlocError(
                        f"{path}:{number}: field '{names[i]}': '{part}' is not a number"
                    ) from None
                if not math.isfinite(value):
                    raise MomlocError(f"{path}:{number}: field '{names[i]}': {part} is not finite")
                if i < 2 and value != int(value):
                    raise MomlocError(
                        f"{path}:{number}: field '{names[i]}': {part} is not an integer"
                    )
                values.append(value)
            out.append((number, values))
    return out


def read_mot(path: str | os.PathLike[str]) -> MotBoxes:
    """A MOTChallenge detection file (see the module docstring)."""
    path = Path(path)
    records = _records(path, MOT_FIELDS, 6)
    frame, ids, boxes, scores = [], [], [], []
    for number, v in records:
        if v[4] < 0 or v[5] < 0:
            field = "bb_width" if v[4] < 0 else "bb_height"
            raise MomlocError(f"{path}:{number}: field '{field}': negative")
        if v[0] < 0:
            raise MomlocError(f"{path}:{number}: field 'frame': negative")
        frame.append(int(v[0]))
        ids.append(int(v[1]))
        boxes.append([v[2], v[3], v[2] + v[4], v[3] + v[5]])
        conf = v[6] if len(v) > 6 else -1.0
        scores.append(1.0 if conf == -1 else conf)
    return MotBoxes(
        np.asarray(frame, np.int64),
        np.asarray(ids, np.int64),
        np.asarray(boxes, np.float32).reshape(-1, 4),
        np.asarray(scores, np.float32),
    )


def read_positions(path: str | os.PathLike[str]) -> Positions:
    """A positions file (see the module docstring); a (frame, id) given twice is an error."""
    path = Path(path)
    records = _records(path, POSITION_FIELDS, 4)
    if not records:
        raise MomlocError(f"{path}: no positions")
    seen: dict[tuple[int, int], int] = {}
    for number, v in records:
        key = (int(v[0]), int(v[1]))
        if key in seen:
            raise MomlocError(
                f"{path}:{number}: field 'id': person {key[1]} already at frame {key[0]} "
                f"(line {seen[key]})"
            )
        seen[key] = number
    a = np.asarray([v[:4] for _, v in records], np.float64)
    return Positions(a[:, 0].astype(np.int64), a[:, 1].astype(np.int64), a[:, 2:4])


def build_replay(
    cameras: Sequence[MotBoxes], image_sizes: Sequence[tuple[int, int]], fps: float
) -> DetectionsReplay:
    """Every box of every camera (ids ignored), in each file's order."""
    return DetectionsReplay(
        frame=np.concatenate([c.frame for c in cameras]),
        camera=np.concatenate([np.full(len(c.frame), k) for k, c in enumerate(cameras)]),
        boxes=np.concatenate([c.boxes for c in cameras]),
        scores=np.concatenate([c.scores for c in cameras]),
        image_size=np.asarray(image_sizes, np.int32),
        fps=fps,
    )


def build_dataset(
    cameras: Sequence[MotBoxes],
    positions: Positions,
    image_sizes: Sequence[tuple[int, int]],
    names: Sequence[str] | None = None,
) -> MomDataset:
    """The dataset v1 of the positions' people (see the module docstring); ``names`` name the
    camera files in errors."""
    names = list(names or [f"camera {k}" for k in range(len(cameras))])
    index = {
        (int(f), int(i)): r
        for r, (f, i) in enumerate(zip(positions.frame, positions.id, strict=True))
    }
    boxes = np.full((len(index), len(cameras), 4), np.nan, np.float32)
    for k, cam in enumerate(cameras):
        if not cam.has_ids:
            raise MomlocError(f"{names[k]}: field 'id': no row carries an id (all -1): no dataset")
        taken: set[tuple[int, int]] = set()
        for f, i, box in zip(cam.frame.tolist(), cam.id.tolist(), cam.boxes, strict=True):
            if i < 0:
                continue
            if (f, i) in taken:
                raise MomlocError(f"{names[k]}: field 'id': id {i} has two boxes at frame {f}")
            taken.add((f, i))
            row = index.get((f, i))
            if row is not None:
                boxes[row, k] = box
    seen = np.any(np.isfinite(boxes).all(axis=2), axis=1)
    if not seen.any():
        raise MomlocError("positions: no (frame, id) of the positions file has a box in any camera")
    return MomDataset(
        world=positions.world[seen].astype(np.float32),
        boxes=boxes[seen],
        frame=positions.frame[seen],
        track=positions.id[seen],
        image_size=np.asarray(image_sizes, np.int32),
    )


def parse_size(text: str) -> tuple[int, int]:
    """``"1920x1024"`` -> (1920, 1024)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise MomlocError(f"--image-size {text}: not WIDTHxHEIGHT") from None
    if w <= 0 or h <= 0:
        raise MomlocError(f"--image-size {text}: width and height must be positive")
    return w, h
