"""MoM dataset v1: one row per observed person instance, stored as ``.npz``.

The format is a contract other tools read (see ARCHITECTURE.md):

===========  ===========================  =================================================
key          dtype, shape                 meaning
===========  ===========================  =================================================
world        float32 [N, 2] or [N, 3]     ground-truth floor position x, y (z) in metres
boxes        float32 [N, K, 4]            per camera: xmin, ymin, xmax, ymax (all NaN: unseen)
keypoints    float32 [N, K, J, 3], opt.   x, y, confidence (NaN where missing; COCO-17 if J=17)
frame        int64 [N]                    time index, monotonic per track
track        int64 [N]                    person id
image_size   int32 [K, 2]                 width, height of each camera's images
===========  ===========================  =================================================

Validation is strict about meaning and lenient about width: a float64 ``boxes`` array is accepted
and stored as float32, but a string or integer ``boxes`` array is rejected. Every rejection raises
:class:`DatasetError` whose message names the key and what is wrong, so the CLI can print one line.

Example::

    data = MomDataset.load("room.npz")
    print(data.n, data.num_cameras, data.visibility())
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.atomic import atomic_write
from common.errors import MomlocError

MAX_CAMERAS = 9
REQUIRED_KEYS = ("world", "boxes", "frame", "track", "image_size")
OPTIONAL_KEYS = ("keypoints",)
_FLOAT_KEYS = ("world", "boxes", "keypoints")


class DatasetError(MomlocError):
    """A dataset file or array set that does not follow MoM dataset v1."""


@dataclass(frozen=True)
class MomDataset:
    """A validated MoM dataset v1 held in memory (arrays already in their v1 dtypes)."""

    world: np.ndarray
    boxes: np.ndarray
    frame: np.ndarray
    track: np.ndarray
    image_size: np.ndarray
    keypoints: np.ndarray | None = None

    def __post_init__(self) -> None:
        arrays = {key: getattr(self, key) for key in (*REQUIRED_KEYS, *OPTIONAL_KEYS)}
        normalised = validate_arrays({k: v for k, v in arrays.items() if v is not None})
        for key, value in normalised.items():
            object.__setattr__(self, key, value)

    @property
    def n(self) -> int:
        """Number of person instances (rows)."""
        return int(self.world.shape[0])

    @property
    def num_cameras(self) -> int:
        return int(self.boxes.shape[1])

    def visible(self) -> np.ndarray:
        """Bool [N, K]: camera k sees instance i (its box is finite)."""
        return np.isfinite(self.boxes).all(axis=-1)

    def visibility(self) -> np.ndarray:
        """Fraction of instances each camera sees, float [K]."""
        return self.visible().mean(axis=0)

    def subset(self, rows: np.ndarray) -> MomDataset:
        """The rows selected by an index or bool mask, as a new dataset."""
        return MomDataset(
            world=self.world[rows],
            boxes=self.boxes[rows],
            frame=self.frame[rows],
            track=self.track[rows],
            image_size=self.image_size,
            keypoints=None if self.keypoints is None else self.keypoints[rows],
        )

    def arrays(self) -> dict[str, np.ndarray]:
        out = {key: getattr(self, key) for key in REQUIRED_KEYS}
        if self.keypoints is not None:
            out["keypoints"] = self.keypoints
        return out

    def summary(self) -> str:
        """One line: instances, cameras, visibility per camera."""
        seen = ", ".join(f"cam{k} {v:.0%}" for k, v in enumerate(self.visibility()))
        sizes = sorted({f"{w}x{h}" for w, h in self.image_size.tolist()})
        tracks = len(np.unique(self.track))
        return (
            f"{self.n} instances, {tracks} tracks, {self.num_cameras} cameras "
            f"({', '.join(sizes)}); visible: {seen}"
        )

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write atomically (:mod:`common.atomic`)."""
        arrays = self.arrays()

        def produce(tmp: Path) -> None:
            with open(tmp, "wb") as handle:  # a handle: np.savez would append ".npz" to a name
                np.savez_compressed(handle, allow_pickle=False, **arrays)

        return atomic_write(path, produce)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> MomDataset:
        """Read and validate a ``.npz`` file; every problem raises :class:`DatasetError`."""
        arrays = read_npz(path, DatasetError)
        try:
            return cls(**validate_arrays(arrays))
        except DatasetError as error:
            raise DatasetError(f"{path}: {error}") from None


def read_npz(
    path: str | os.PathLike[str], error: type[MomlocError] = MomlocError
) -> dict[str, np.ndarray]:
    """All arrays of an ``.npz`` file (never unpickled); a missing or broken file raises
    ``error`` (a :class:`MomlocError`) naming the file."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{path}: no such file")
    if not zipfile.is_zipfile(path):
        raise error(f"{path}: not a readable .npz file (not a zip archive)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            return {key: archive[key] for key in archive.files}
    except (zipfile.BadZipFile, OSError, EOFError) as failure:
        raise error(f"{path}: not a readable .npz file ({failure})") from None
    except ValueError as failure:  # object arrays need pickle, which we never allow
        raise error(f"{path}: unsupported array content ({failure})") from None


def _as_dtype(key: str, value: object, kind: str, dtype: type) -> np.ndarray:
    """Cast within a dtype kind, refuse a change of kind (integer metre grids suit world)."""
    array = np.asarray(value)
    accepted = {"f": "fiu" if key == "world" else "f", "i": "iu"}[kind]
    if array.dtype.kind not in accepted:
        wanted = {"f": "floating-point", "i": "integer"}[kind]
        raise DatasetError(f"key '{key}': dtype {array.dtype} is not {wanted}")
    return array.astype(dtype, copy=False)


def _check_box_rows(boxes: np.ndarray) -> None:
    nan = np.isnan(boxes)
    partial = nan.any(axis=-1) & ~nan.all(axis=-1)
    if partial.any():
        i, k = np.argwhere(partial)[0]
        raise DatasetError(
            f"key 'boxes': row {i} camera {k} is partly NaN (a missing view must be all NaN)"
        )
    seen = ~nan.all(axis=-1)
    flipped = seen & ((boxes[..., 2] < boxes[..., 0]) | (boxes[..., 3] < boxes[..., 1]))
    if flipped.any():
        i, k = np.argwhere(flipped)[0]
        raise DatasetError(
            f"key 'boxes': row {i} camera {k} has xmax < xmin or ymax < ymin ({boxes[i, k]})"
        )


def validate_arrays(arrays: Mapping[str, object]) -> dict[str, np.ndarray]:
    """Check a key → array mapping against v1 and return it in v1 dtypes.

    Raises :class:`DatasetError` naming the first offending key.
    """
    unknown = sorted(set(arrays) - set(REQUIRED_KEYS) - set(OPTIONAL_KEYS))
    if unknown:
        raise DatasetError(f"key '{unknown[0]}': not part of MoM dataset v1")
    for key in REQUIRED_KEYS:
        if key not in arrays:
            raise DatasetError(f"key '{key}': missing")

    out: dict[str, np.ndarray] = {}
    for key in _FLOAT_KEYS:
        if key in arrays:
            out[key] = _as_dtype(key, arrays[key], "f", np.float32)
    out["frame"] = _as_dtype("frame", arrays["frame"], "i", np.int64)
    out["track"] = _as_dtype("track", arrays["track"], "i", np.int64)
    out["image_size"] = _as_dtype("image_size", arrays["image_size"], "i", np.int32)

    world, boxes = out["world"], out["boxes"]
    if world.ndim != 2 or world.shape[1] not in (2, 3):
        raise DatasetError(f"key 'world': shape {world.shape} is not [N, 2] or [N, 3]")
    n = world.shape[0]
    if n == 0:
        raise DatasetError("key 'world': the dataset has no rows")
    if boxes.ndim != 3 or boxes.shape[2] != 4:
        raise DatasetError(f"key 'boxes': shape {boxes.shape} is not [N, K, 4]")
    k = boxes.shape[1]
    if not 1 <= k <= MAX_CAMERAS:
        raise DatasetError(f"key 'boxes': {k} cameras, expected 1 to {MAX_CAMERAS}")
    for key in ("boxes", "frame", "track"):
        if out[key].shape[0] != n:
            raise DatasetError(f"key '{key}': {out[key].shape[0]} rows but 'world' has {n}")
    for key in ("frame", "track"):
        if out[key].ndim != 1:
            raise DatasetError(f"key '{key}': shape {out[key].shape} is not [N]")
    size = out["image_size"]
    if size.ndim != 2 or size.shape[1] != 2:
        raise DatasetError(f"key 'image_size': shape {size.shape} is not [K, 2]")
    if size.shape[0] != k:
        raise DatasetError(f"key 'image_size': {size.shape[0]} cameras but 'boxes' has {k}")
    if (size <= 0).any():
        raise DatasetError("key 'image_size': width and height must be positive")

    if not np.isfinite(world).all():
        raise DatasetError("key 'world': contains NaN or infinite values")
    if np.isinf(boxes).any():
        raise DatasetError("key 'boxes': contains infinite values")
    _check_box_rows(boxes)

    if "keypoints" in out:
        keypoints = out["keypoints"]
        if keypoints.ndim != 4 or keypoints.shape[3] != 3:
            raise DatasetError(f"key 'keypoints': shape {keypoints.shape} is not [N, K, J, 3]")
        if keypoints.shape[:2] != (n, k):
            raise DatasetError(
                f"key 'keypoints': leading shape {keypoints.shape[:2]} does not match "
                f"[N, K] = {(n, k)} of 'boxes'"
            )
        if np.isinf(keypoints).any():
            raise DatasetError("key 'keypoints': contains infinite values")
    return out
