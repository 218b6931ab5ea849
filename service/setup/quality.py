"""Per-mark quality of a recording: how many frames each camera contributed at each mark.

A camera that saw the person in only a few of the frames recorded on a mark gives the model
little to learn there (the model will be weak around that mark from that camera's view), and the
user can fix it at once: move the camera, or record the mark again while nobody walks through.
The warning threshold is a judgement, not a measurement: a camera that kept fewer than
``MIN_SHARE`` of the frame sets offered on a mark is named. A mark outside a camera's view is
warned about too; that can be intended (the page says which camera, the user decides).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from service.setup.collector import DatasetAppender, Step, mark_key
from service.setup.marks import FloorMark

MIN_SHARE = 0.3


class MarkQuality:
    """Counts, for the marks of one collection, frame sets offered and rows kept per camera."""

    def __init__(self, marks: list[FloorMark], num_cameras: int) -> None:
        self._marks = {m.name: m for m in marks}
        self._by_key = {mark_key(m.x, m.y): m.name for m in marks}
        self._offered = dict.fromkeys(self._marks, 0)
        self._kept = {name: np.zeros(num_cameras, int) for name in self._marks}
        self._rows = dict.fromkeys(self._marks, 0)
        self._recording: str | None = None
        self.finished: list[str] = []  # marks whose record step is over, in order

    def counting(self, writer: DatasetAppender) -> _CountingWriter:
        """``writer`` with its ``add`` counted (the collector writes through it)."""
        return _CountingWriter(writer, self)

    def frame(self, step: Step, cameras_seeing: list[int]) -> None:
        """One frame set of ``step`` was shown to the collector."""
        recording = step.mark.name if step.kind == "record" and step.mark else None
        if self._recording is not None and recording != self._recording:
            self.finish()
        if recording is not None and recording in self._offered:
            self._offered[recording] += 1
        self._recording = recording

    def finish(self) -> None:
        """The current record step is over (next step, or the end of the collection)."""
        if self._recording is not None and self._recording not in self.finished:
            self.finished.append(self._recording)
        self._recording = None

    def _row(self, world: Any, boxes: np.ndarray) -> None:
        name = self._by_key.get(mark_key(float(world[0]), float(world[1])))
        if name is not None:
            self._rows[name] += 1
            self._kept[name] += np.isfinite(np.asarray(boxes)).all(axis=1)

    def report(self) -> list[dict[str, Any]]:
        """Finished marks: frames offered and kept per camera, with warnings naming the camera."""
        out = []
        for name in self.finished:
            offered, kept = self._offered[name], self._kept[name]
            warnings = [
                f"camera {k} saw you in {int(n)} of {offered} frames at {name}: the model will "
                f"be weak there; check that camera's view and record {name} again"
                for k, n in enumerate(kept)
                if n < MIN_SHARE * offered
            ]
            out.append(
                {
                    "mark": name,
                    "frames": offered,
                    "kept": self._rows[name],
                    "per_camera": [int(n) for n in kept],
                    "warnings": warnings,
                }
            )
        return out


class _CountingWriter:
    """Delegates to a :class:`DatasetAppender`, counting the rows it is given per mark.

    A :class:`~service.setup.collector.RowWriter` spelled out member by member (no
    ``__getattr__`` forwarding, which would type every other attribute as ``Any``)."""

    def __init__(self, writer: DatasetAppender, quality: MarkQuality) -> None:
        self._writer, self._quality = writer, quality

    @property
    def new_rows(self) -> int:
        return self._writer.new_rows

    def new_track(self) -> int:
        return self._writer.new_track()

    def add(self, world: Any, boxes: np.ndarray, keypoints: np.ndarray | None, track: int) -> None:
        self._quality._row(world, boxes)
        self._writer.add(world, boxes, keypoints, track)

    def mark_done(self, mark: FloorMark) -> None:
        self._writer.mark_done(mark)

    def flush(self) -> None:
        self._writer.flush()
