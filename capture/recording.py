"""Recordings: every camera's frames with their capture times, as the pipeline saw them.

Format (``momloc-recording`` version 1), one folder::

    manifest.json    format, version, frame-set count, time span, and per camera its name,
                     video and timestamps file, frame size, frame count and measured fps
    cam0.avi         camera 0's frames, MJPG (what webcams send; OpenCV writes and reads it
                     everywhere without extra codecs), one image per *new* frame
    cam0.csv         ``index,timestamp,seq``: per image of cam0.avi its wall-clock capture
                     time (s) and the camera worker's frame number (gaps = frames dropped live)
    frame_sets.csv   ``set,cam0,cam1,...``: per frame set the image index each camera
                     contributed (-1: none); a repeated index is a camera that had no new frame

Why frame sets are stored and not only per-camera streams: the live pipeline fuses the newest
frame of every camera at the moment it looks, so which frames were fused together (and which
camera repeated or missed) is part of what happened. Offline tracking replays exactly those sets;
a per-camera replay (``type: file`` cameras, :mod:`capture.replay`) needs only the video and its
timestamps. Images are stored once per camera even when several sets reuse them.

Why the timestamps live in CSV beside the video and not in the container: AVI has one nominal
frame rate, webcams do not keep it (jitter, dropped frames); the recorded times are what
tracking's velocities and time-outs must see again. The container's rate is the measured mean.

``manifest.json`` is written last, atomically (:mod:`common.atomic`): a folder without it is an
interrupted recording and is refused by :class:`Recording`. ``momloc record`` finalises the
manifest on Ctrl-C, so stopping a recording by hand keeps what was recorded.

Example::

    with RecordingWriter(out, ["left", "right"]) as writer:
        writer.add(rig.frame_set())
    for index, frame_set in Recording.open(out).frame_sets():
        ...
"""

from __future__ import annotations

import contextlib
import csv
import json
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import cv2
import numpy as np

from capture.rig import FrameSet
from capture.worker import Frame
from common.atomic import atomic_write_json
from common.errors import MomlocError

FORMAT = "momloc-recording"
VERSION = 1
MANIFEST = "manifest.json"
FRAME_SETS = "frame_sets.csv"
MAX_SKEW_S = 0.05  # capture.rig.CameraRig's default: frames further apart are marked stale
_FOURCC = "MJPG"


def video_name(camera: int) -> str:
    return f"cam{camera}.avi"


def timestamps_path(video: Path) -> Path:
    """The timestamps file of a recorded camera video (``cam0.avi`` -> ``cam0.csv``)."""
    return video.with_suffix(".csv")


def check_new_folder(out: str | Path) -> Path:
    """``out`` as a Path if a recording may be written there (absent or an empty folder)."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise MomlocError(f"{out}: exists and is not an empty folder (not overwritten)")
    return out


class RecordingWriter:
    """Writes frame sets into a new recording folder; :meth:`close` writes the manifest.

    ``fps`` is the nominal rate put in the AVI headers (players use it; replay does not).
    """

    def __init__(
        self,
        out: str | Path,
        names: Sequence[str],
        *,
        fps: float = 30.0,
        source: dict[str, Any] | None = None,
    ) -> None:
        self.out = check_new_folder(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.names = [str(n) for n in names]
        self.fps, self.source = float(fps), source or {}
        k = len(self.names)
        self._writers: list[cv2.VideoWriter | None] = [None] * k
        self._sizes: list[tuple[int, int] | None] = [None] * k
        self._counts = [0] * k
        self._last_seq: list[int | None] = [None] * k
        self._stamps: list[list[float]] = [[] for _ in range(k)]
        self._open = contextlib.ExitStack()  # the CSV files stay open while recording
        files = [self._open.enter_context(_csv_file(self.out / f"cam{c}.csv")) for c in range(k)]
        self._rows = [csv.writer(f) for f in files]
        for row in self._rows:
            row.writerow(["index", "timestamp", "seq"])
        sets_file = self._open.enter_context(_csv_file(self.out / FRAME_SETS))
        self._sets = csv.writer(sets_file)
        self._sets.writerow(["set", *(f"cam{c}" for c in range(k))])
        self.frame_sets = 0
        self._closed = False

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def counts(self) -> list[int]:
        """Images written so far, per camera."""
        return list(self._counts)

    def add(self, frame_set: FrameSet) -> None:
        """Store one frame set: new images are appended, repeated frames only referenced."""
        if len(frame_set.frames) != len(self.names):
            raise MomlocError(
                f"recording: frame set has {len(frame_set.frames)} cameras, "
                f"expected {len(self.names)}"
            )
        used = [self._store(k, f) for k, f in enumerate(frame_set.frames)]
        self._sets.writerow([self.frame_sets, *used])
        self.frame_sets += 1

    def _store(self, k: int, frame: Frame | None) -> int:
        if frame is None or frame.image is None:
            return -1
        if self._last_seq[k] == frame.seq and self._counts[k] > 0:
            return self._counts[k] - 1  # the camera had no newer frame: same image again
        h, w = frame.image.shape[:2]
        writer, size = self._writers[k], self._sizes[k]
        if writer is None or size is None:
            fourcc = cv2.VideoWriter.fourcc(*_FOURCC)
            path = str(self.out / video_name(k))
            writer = cv2.VideoWriter(path, fourcc, self.fps, (w, h))
            if not writer.isOpened():
                raise MomlocError(f"{path}: OpenCV cannot write MJPG video here")
            self._writers[k], self._sizes[k] = writer, (w, h)
        elif size != (w, h):
            raise MomlocError(
                f"camera {self.names[k]}: frame size changed from "
                f"{size[0]}x{size[1]} to {w}x{h} during the recording"
            )
        writer.write(np.ascontiguousarray(frame.image))
        index = self._counts[k]
        self._rows[k].writerow([index, f"{frame.timestamp:.6f}", int(frame.seq)])
        self._stamps[k].append(float(frame.timestamp))
        self._counts[k] += 1
        self._last_seq[k] = frame.seq
        return index

    def close(self) -> Path:
        """Finish the videos and write the manifest (atomically); idempotent."""
        manifest = self.out / MANIFEST
        if self._closed:
            return manifest
        self._closed = True
        for writer in self._writers:
            if writer is not None:
                writer.release()
        self._open.close()
        stamps = [t for per_camera in self._stamps for t in per_camera]
        cameras = []
        for k, name in enumerate(self.names):
            times = np.array(self._stamps[k])
            fps = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0
            size = self._sizes[k] or (0, 0)
            cameras.append(
                {
                    "name": name,
                    "video": video_name(k),
                    "timestamps": timestamps_path(Path(video_name(k))).name,
                    "width": size[0],
                    "height": size[1],
                    "frames": self._counts[k],
                    "fps": round(float(fps), 3),
                }
            )
        atomic_write_json(
            manifest,
            {
                "format": FORMAT,
                "version": VERSION,
                "created": time.time(),
                "frame_sets": self.frame_sets,
                "start": min(stamps) if stamps else None,
                "end": max(stamps) if stamps else None,
                "cameras": cameras,
                "source": self.source,
            },
        )
        return manifest


def _csv_file(path: Path) -> TextIO:
    """Opened for the whole recording; closed by :meth:`RecordingWriter.close`."""
    return path.open("w", newline="")


@dataclass(frozen=True)
class RecordedCamera:
    name: str
    video: Path
    timestamps: Path
    width: int
    height: int
    frames: int
    fps: float


def read_timestamps(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Capture times [N] (s) and source frame numbers [N] of a recorded camera's images."""
    try:
        with open(path, newline="") as handle:
            rows = list(csv.reader(handle))
    except OSError as error:
        raise MomlocError(f"{path}: cannot read timestamps ({error.strerror})") from None
    if not rows or rows[0] != ["index", "timestamp", "seq"]:
        raise MomlocError(f"{path}: not a recording timestamps file (header index,timestamp,seq)")
    try:
        table = np.array([[float(v) for v in row] for row in rows[1:]]).reshape(-1, 3)
    except ValueError:
        raise MomlocError(f"{path}: a row is not three numbers") from None
    if not np.array_equal(table[:, 0], np.arange(len(table))):
        raise MomlocError(f"{path}: image indices are not 0, 1, 2, ...")
    if len(table) > 1 and np.any(np.diff(table[:, 1]) < 0):
        raise MomlocError(f"{path}: timestamps go backwards")
    return table[:, 1], table[:, 2].astype(np.int64)


class Recording:
    """A finished recording folder, validated at :meth:`open`; iterate :meth:`frame_sets`."""

    def __init__(self, folder: Path, meta: dict[str, Any], cameras: list[RecordedCamera]) -> None:
        self.folder, self.meta, self.cameras = folder, meta, cameras

    @classmethod
    def open(cls, folder: str | Path) -> Recording:
        folder = Path(folder)
        if not folder.is_dir():
            raise MomlocError(f"{folder}: no such recording folder")
        path = folder / MANIFEST
        if not path.is_file():
            raise MomlocError(f"{folder}: not a recording (no {MANIFEST}; interrupted?)")
        try:
            meta = json.loads(path.read_text())
        except (OSError, ValueError):
            raise MomlocError(f"{path}: unreadable or not JSON") from None
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise MomlocError(f"{path}: format is not {FORMAT!r}")
        if meta.get("version") != VERSION:
            raise MomlocError(f"{path}: version {meta.get('version')!r}, this momloc reads 1")
        try:
            cameras = [
                RecordedCamera(
                    name=str(c["name"]),
                    video=folder / str(c["video"]),
                    timestamps=folder / str(c["timestamps"]),
                    width=int(c["width"]),
                    height=int(c["height"]),
                    frames=int(c["frames"]),
                    fps=float(c["fps"]),
                )
                for c in meta["cameras"]
            ]
            int(meta["frame_sets"])
        except (KeyError, TypeError, ValueError):
            raise MomlocError(f"{path}: cameras or frame_sets missing or malformed") from None
        if not cameras:
            raise MomlocError(f"{path}: no cameras")
        for c in cameras:
            if c.frames and not c.video.is_file():
                raise MomlocError(f"{folder}: video {c.video.name} is missing")
        return cls(folder, meta, cameras)

    @property
    def num_cameras(self) -> int:
        return len(self.cameras)

    @property
    def image_sizes(self) -> list[tuple[int, int]]:
        return [(c.width, c.height) for c in self.cameras]

    def __len__(self) -> int:
        return int(self.meta["frame_sets"])

    def _set_table(self) -> np.ndarray:
        path = self.folder / FRAME_SETS
        try:
            with open(path, newline="") as handle:
                rows = list(csv.reader(handle))[1:]
            table = np.array([[int(v) for v in row] for row in rows], np.int64)
        except (OSError, ValueError):
            raise MomlocError(f"{path}: missing or not integers") from None
        table = table.reshape(-1, self.num_cameras + 1)
        if len(table) != len(self):
            raise MomlocError(f"{path}: {len(table)} frame sets, the manifest says {len(self)}")
        return table[:, 1:]

    def frame_sets(self) -> Iterator[tuple[int, FrameSet]]:
        """``(index, FrameSet)`` in recorded order: the frames, capture times and skew the
        pipeline had live (a camera that repeated its frame repeats the same image and seq)."""
        table = self._set_table()
        readers = [_CameraReader(c) for c in self.cameras]
        try:
            for index, used in enumerate(table):
                pairs = enumerate(zip(readers, used, strict=True))
                frames = [reader.frame(k, int(j)) for k, (reader, j) in pairs]
                yield index, _frame_set(frames)
        finally:
            for reader in readers:
                reader.close()


def _frame_set(frames: list[Frame | None]) -> FrameSet:
    times = [f.timestamp for f in frames if f is not None]
    if not times:
        return FrameSet(frames=frames, skew=0.0, stale=[False] * len(frames))
    newest = max(times)
    stale = [f is not None and newest - f.timestamp > MAX_SKEW_S for f in frames]
    return FrameSet(frames=frames, skew=newest - min(times), stale=stale)


class _CameraReader:
    """Decodes one camera's video forward only, caching the newest image for repeats."""

    def __init__(self, camera: RecordedCamera) -> None:
        self.camera = camera
        self.times, self.seqs = read_timestamps(camera.timestamps)
        if len(self.times) != camera.frames:
            raise MomlocError(
                f"{camera.timestamps}: {len(self.times)} rows, the manifest says {camera.frames}"
            )
        self._capture: cv2.VideoCapture | None = None
        self._decoded = -1
        self._current: Frame | None = None

    def frame(self, k: int, index: int) -> Frame | None:
        if index < 0:
            return None
        if index >= len(self.times) or index < self._decoded:
            raise MomlocError(f"{self.camera.video}: frame sets use image {index} out of order")
        if self._capture is None:
            self._capture = cv2.VideoCapture(str(self.camera.video))
            if not self._capture.isOpened():
                raise MomlocError(f"{self.camera.video}: cannot be opened as video")
        while self._decoded < index:
            ok, image = self._capture.read()
            if not ok:
                raise MomlocError(
                    f"{self.camera.video}: truncated, image {self._decoded + 1} does not decode"
                )
            self._decoded += 1
            self._current = Frame(
                camera=k,
                image=image,
                timestamp=float(self.times[self._decoded]),
                seq=int(self.seqs[self._decoded]),
            )
        return self._current

    def close(self) -> None:
        if self._capture is not None:
            self._capture.release()
