"""Guided collection at floor marks: the plan, the per-frame filter and a loss-free writer.

The plan is a list of steps the user (or the simulated person) follows: move to a mark, a
countdown, then hold still on it (swaying and turning in place) while frames are recorded; in walk
mode the walk from one mark to the next is recorded too, labelled by linear interpolation along the
straight line at a steady pace. Each recorded frame becomes one dataset row whose ``world`` is the
mark (or the interpolated point).

Frame filter: a frame is kept when no camera sees more than one person and at least one camera
sees exactly one (``require_all_cameras`` asks for exactly one in *every* camera). Keeping frames
where a camera sees nobody is deliberate: marks outside one camera's view still teach the model,
and real missed detections are the missing views the model must cope with.

Nothing is lost: rows are appended to the output file by rewriting it atomically (temporary file,
fsync, rename) every couple of seconds and after every step, so a crash or Ctrl-C keeps all but
the last moments. Re-running on the same file resumes: existing rows stay, marks already recorded
are left out of the plan (:meth:`DatasetAppender.has_mark`), and new marks extend the data set.

A mark counts as recorded only when its ``record`` step ran to the end (and kept a row): rows
alone do not say that, since a crash in the middle of a mark leaves some. Completed marks are
listed in a progress file next to the data (``<out>.marks.json``), rewritten atomically right
after the rows it vouches for, so a crash between the two writes only means re-recording a mark.
For a data file from before progress files existed, its first rows (``legacy_rows`` in the
progress file) keep the old rule: a mark with rows among them counts as recorded.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Protocol, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from common.atomic import atomic_write_json
from common.errors import MomlocError
from models.data.dataset import MomDataset
from service.setup.marks import FloorMark

StepKind = Literal["move", "countdown", "record", "walk"]
RECORDING: tuple[StepKind, ...] = ("record", "walk")
WALK_SPEED_MPS = 0.6  # a slow, steady pace a person can keep while being recorded
MOVE_SPEED_MPS = 1.0
FLUSH_EVERY_S = 2.0
MARK_TOLERANCE_M = 0.01
_ROW_KEYS = ("world", "boxes", "keypoints", "frame", "track")


@dataclass(frozen=True)
class Step:
    kind: StepKind
    start: tuple[float, float]
    end: tuple[float, float]
    seconds: float
    instruction: str
    mark: FloorMark | None = None

    def position(self, fraction: float) -> tuple[float, float]:
        """Label at ``fraction`` of the step: the straight line from start to end."""
        f = min(max(fraction, 0.0), 1.0)
        return (
            self.start[0] + f * (self.end[0] - self.start[0]),
            self.start[1] + f * (self.end[1] - self.start[1]),
        )


def plan_steps(
    marks: list[FloorMark],
    seconds: float,
    *,
    start: tuple[float, float],
    walk: bool = False,
    move_s: float = 5.0,
    countdown_s: float = 3.0,
) -> list[Step]:
    """The instructions for recording ``seconds`` on every mark (and the walks, in walk mode)."""
    if seconds <= 0:
        raise MomlocError(f"--seconds must be positive, got {seconds}")
    steps: list[Step] = []
    here = start
    for i, mark in enumerate(marks):
        there = (mark.x, mark.y)
        distance = math.dist(here, there)
        if walk and i > 0:
            walk_s = max(distance / WALK_SPEED_MPS, 1.0)
            steps.append(
                Step("walk", here, there, walk_s, f"walk slowly and steadily to {mark.name}", mark)
            )
        else:
            travel = max(move_s, distance / MOVE_SPEED_MPS)
            steps.append(Step("move", here, there, travel, f"go to mark {mark.name}", mark))
            steps.append(
                Step("countdown", there, there, countdown_s, f"stand on {mark.name}", mark)
            )
        steps.append(
            Step("record", there, there, seconds, f"stay on {mark.name}, sway and turn", mark)
        )
        here = there
    return steps


@dataclass(frozen=True)
class FeedFrame:
    """One frame set's detections: per camera boxes [M, 4] and keypoints [M, J, 3] or None."""

    t: float
    boxes: list[np.ndarray]
    keypoints: list[np.ndarray | None] | None = None


class DetectionFeed(Protocol):
    """Where collection gets detections: live cameras + detector, or the synthetic scene."""

    image_sizes: np.ndarray

    def prepare(self, steps: list[Step]) -> None:
        """Called once with the whole plan before the first step."""
        ...

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        """Frame sets for the duration of ``step`` (a simulated person follows it)."""
        ...

    def close(self) -> None:
        """Release cameras."""
        ...


def frame_row(
    frame: FeedFrame, require_all_cameras: bool
) -> tuple[np.ndarray, np.ndarray | None] | None:
    """The frame as one row (boxes [K,4], keypoints [K,J,3] or None when the feed has none), or
    None when it must be dropped."""
    counts = [len(b) for b in frame.boxes]
    if max(counts) > 1 or max(counts) == 0 or (require_all_cameras and min(counts) < 1):
        return None
    boxes = np.full((len(counts), 4), np.nan, np.float32)
    keypoints = None
    if frame.keypoints is not None:
        joints = next((kp.shape[1] for kp in frame.keypoints if kp is not None and len(kp)), 17)
        keypoints = np.full((len(counts), joints, 3), np.nan, np.float32)
    for k, camera_boxes in enumerate(frame.boxes):
        if len(camera_boxes):
            boxes[k] = camera_boxes[0]
            camera_keypoints = None if frame.keypoints is None else frame.keypoints[k]
            if keypoints is not None and camera_keypoints is not None:
                keypoints[k] = camera_keypoints[0]
    return boxes, keypoints


PROGRESS_FORMAT = "momloc-collect-progress-v1"


def progress_path(path: Path) -> Path:
    """The progress file that lists the completed marks of dataset ``path``."""
    return path.with_name(path.name + ".marks.json")


@dataclass
class DatasetAppender:
    """Appends rows to a dataset v1 file, keeping what it already held."""

    path: Path
    image_sizes: np.ndarray
    _existing: MomDataset | None = None
    _rows: dict[str, list] = field(default_factory=lambda: {k: [] for k in _ROW_KEYS})
    next_frame: int = 0
    next_track: int = 0
    _done: list[dict] = field(default_factory=list)  # completed marks (progress file)
    _row_keys: set[tuple[int, int]] = field(default_factory=set)  # labels of all rows, in cm
    _legacy_keys: set[tuple[int, int]] = field(default_factory=set)  # rows older than progress
    _legacy_rows: int = 0
    _done_keys: set[tuple[int, int]] = field(default_factory=set)
    _progress_dirty: bool = False
    saved_rows: int = 0  # new rows on disk (the last successful flush), what a status reports

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        if self.path.exists():
            self._existing = MomDataset.load(self.path)
            if not np.array_equal(self._existing.image_size, self.image_sizes):
                raise MomlocError(
                    f"{self.path}: recorded with cameras {self._existing.image_size.tolist()}, "
                    f"now {self.image_sizes.tolist()}; use another --out file"
                )
            self.next_frame = int(self._existing.frame.max()) + 1
            self.next_track = int(self._existing.track.max()) + 1
            labels = self._existing.world[:, :2].tolist()
            self._row_keys = {mark_key(x, y) for x, y in labels}
            progress = _read_progress(progress_path(self.path))
            if progress is None:  # a file from before progress files: all its rows are legacy
                self._legacy_rows, self._progress_dirty = len(labels), True
            else:
                self._done, self._legacy_rows = progress
            self._legacy_keys = {mark_key(x, y) for x, y in labels[: self._legacy_rows]}
            self._done_keys = {mark_key(d["x"], d["y"]) for d in self._done}

    @property
    def existing_rows(self) -> int:
        return 0 if self._existing is None else self._existing.n

    @property
    def new_rows(self) -> int:
        return len(self._rows["world"])

    def has_rows_at(self, mark: FloorMark) -> bool:
        """Whether the file holds rows labelled at this mark (complete or not)."""
        return mark_key(mark.x, mark.y) in self._row_keys

    def has_mark(self, mark: FloorMark) -> bool:
        """Whether this mark's recording completed in an earlier run (see the module doc)."""
        key = mark_key(mark.x, mark.y)
        return key in self._legacy_keys or key in self._done_keys

    def mark_done(self, mark: FloorMark) -> None:
        """Record that ``mark`` completed; written with the next :meth:`flush`."""
        if not self.has_mark(mark):
            self._done.append({"name": mark.name, "x": mark.x, "y": mark.y})
            self._done_keys.add(mark_key(mark.x, mark.y))
        self._progress_dirty = True

    def new_track(self) -> int:
        self.next_track += 1
        return self.next_track - 1

    def add(
        self, world: ArrayLike, boxes: np.ndarray, keypoints: np.ndarray | None, track: int
    ) -> None:
        world = np.asarray(world, np.float32)[:2]
        self._row_keys.add(mark_key(float(world[0]), float(world[1])))
        self._rows["world"].append(world)
        self._rows["boxes"].append(boxes)
        self._rows["keypoints"].append(keypoints)
        self._rows["frame"].append(self.next_frame)
        self._rows["track"].append(track)
        self.next_frame += 1

    def flush(self) -> None:
        """Rewrite the file atomically with the old and the new rows when rows were added since
        the last write (an unchanged file is not written again), then the progress file."""
        if len(self._rows["world"]) > self.saved_rows:
            if not self.path.exists():  # a new file: say "no mark complete" before any row lands
                _write_progress(progress_path(self.path), [], 0)
            self._write_rows()
        if self._progress_dirty and self.path.exists():
            _write_progress(progress_path(self.path), self._done, self._legacy_rows)
            self._progress_dirty = False

    def _write_rows(self) -> None:
        new = {
            "world": np.stack(self._rows["world"]),
            "boxes": np.stack(self._rows["boxes"]),
            "frame": np.array(self._rows["frame"], np.int64),
            "track": np.array(self._rows["track"], np.int64),
        }
        keypoints = self._rows["keypoints"]
        with_keypoints = all(k is not None for k in keypoints) and (
            self._existing is None or self._existing.keypoints is not None
        )
        if with_keypoints:
            new["keypoints"] = np.stack(keypoints)
        if self._existing is not None:
            old = self._existing.arrays()
            old["world"] = old["world"][:, :2]
            new = {key: np.concatenate([old[key], new[key]]) for key in new}
        MomDataset(image_size=self.image_sizes, **new).save(self.path)
        self.saved_rows = len(self._rows["world"])


def forget_mark(path: Path, mark: FloorMark) -> int:
    """Remove ``mark``'s rows and its completed entry from a recording, so it can be recorded
    again (the "record this mark again" of the set-up page); returns the rows removed."""
    path = Path(path)
    data = MomDataset.load(path)
    key = mark_key(mark.x, mark.y)
    at_mark = np.array([mark_key(float(x), float(y)) == key for x, y in data.world[:, :2]], bool)
    progress = _read_progress(progress_path(path))
    done, legacy = progress if progress is not None else ([], data.n)
    done = [d for d in done if mark_key(d["x"], d["y"]) != key]
    legacy -= int(at_mark[:legacy].sum())
    if at_mark.all():
        path.unlink()
        progress_path(path).unlink(missing_ok=True)
        return int(at_mark.sum())
    arrays = data.arrays()
    arrays["world"] = arrays["world"][:, :2]
    kept = {k: v[~at_mark] for k, v in arrays.items() if k != "image_size" and v is not None}
    MomDataset(image_size=data.image_size, **kept).save(path)
    _write_progress(progress_path(path), done, legacy)
    return int(at_mark.sum())


def mark_key(x: float, y: float) -> tuple[int, int]:
    """A label rounded to the centimetre: marks are typed to the centimetre at best."""
    return round(x / MARK_TOLERANCE_M), round(y / MARK_TOLERANCE_M)


def mark_names(path: Path) -> dict[tuple[int, int], str]:
    """The names of dataset ``path``'s completed marks by :func:`mark_key` (none without a
    progress file)."""
    done, _ = _read_progress(progress_path(path)) or ([], 0)
    return {mark_key(d["x"], d["y"]): d["name"] for d in done}


def _read_progress(path: Path) -> tuple[list[dict], int] | None:
    """Completed marks and legacy row count from a progress file; None when there is none."""
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        raise MomlocError(f"{path}: unreadable progress file; delete it to re-record") from None
    done = document.get("done") if isinstance(document, dict) else None
    if document.get("format") != PROGRESS_FORMAT or not isinstance(done, list):
        raise MomlocError(f"{path}: not a {PROGRESS_FORMAT} file; delete it to re-record")
    try:
        marks = [{"name": str(d["name"]), "x": float(d["x"]), "y": float(d["y"])} for d in done]
        return marks, int(document.get("legacy_rows", 0))
    except (KeyError, TypeError, ValueError):
        raise MomlocError(f"{path}: malformed entry under 'done'; delete it") from None


def _write_progress(path: Path, done: list[dict], legacy_rows: int) -> None:
    """Atomic rewrite (:mod:`common.atomic`), like the data file itself."""
    document = {"format": PROGRESS_FORMAT, "done": done, "legacy_rows": legacy_rows}
    atomic_write_json(path, document)


@dataclass(frozen=True)
class Progress:
    """What a user interface shows: the step, how far it is, and what each camera sees."""

    step_index: int
    steps: int
    step: Step
    fraction: float
    cameras_seeing: list[int]
    kept_rows: int


class RowWriter(Protocol):
    """What :func:`collect` writes through: a :class:`DatasetAppender`, or one wrapped to count
    its rows per mark (``MarkQuality.counting`` in :mod:`service.setup.quality`)."""

    @property
    def new_rows(self) -> int: ...

    def new_track(self) -> int: ...

    def add(
        self, world: ArrayLike, boxes: np.ndarray, keypoints: np.ndarray | None, track: int
    ) -> None: ...

    def mark_done(self, mark: FloorMark) -> None: ...

    def flush(self) -> None: ...


Writer = TypeVar("Writer", bound=RowWriter)


def collect(
    feed: DetectionFeed,
    steps: list[Step],
    writer: Writer,
    *,
    require_all_cameras: bool = False,
    on_progress: Callable[[Progress], None] | None = None,
) -> Writer:
    """Run the plan, appending kept frames through ``writer``; flushes on every exit path."""
    try:
        for index, step in enumerate(steps):
            recording = step.kind in RECORDING
            track = writer.new_track() if recording else -1
            first_t = last_flush = None
            kept_before = writer.new_rows
            for frame in feed.frames(step):
                first_t = frame.t if first_t is None else first_t
                fraction = (frame.t - first_t) / step.seconds
                row = frame_row(frame, require_all_cameras) if recording else None
                if row is not None:
                    writer.add(step.position(fraction), row[0], row[1], track)
                if recording and (last_flush is None or frame.t - last_flush >= FLUSH_EVERY_S):
                    writer.flush()
                    last_flush = frame.t
                if on_progress is not None:
                    seeing = [len(b) for b in frame.boxes]
                    on_progress(
                        Progress(index, len(steps), step, fraction, seeing, writer.new_rows)
                    )
            if step.kind == "record" and step.mark is not None and writer.new_rows > kept_before:
                writer.mark_done(step.mark)  # the step ran to its end: the mark is complete
            writer.flush()
    finally:
        writer.flush()
    return writer
