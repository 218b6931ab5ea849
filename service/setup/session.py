"""Guided collection driven from the web page, on the running daemon's own detections.

The daemon's pipeline already detects people in every frame set; a :class:`DetectionTap` receives
those detections (the pipeline calls it, it never waits) and serves them to the collector as a
feed, so collecting costs no second detector run and the live map keeps streaming meanwhile.
A :class:`SetupSession` runs one collection at a time in a thread; the page polls
:meth:`SetupSession.status`. Stopping cancels between frames and keeps every row recorded so far
(the collector flushes on every exit path).
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from common.errors import MomlocError, shorten
from service.setup.arrival import Arrival
from service.setup.collector import (
    DatasetAppender,
    FeedFrame,
    Progress,
    Step,
    collect,
    forget_mark,
    plan_steps,
)
from service.setup.marks import FloorMark
from service.setup.quality import MarkQuality
from service.setup.steps import SetupConflict, SetupSteps

DetectionListener = Callable[[float, list[np.ndarray]], None]  # (capture time, boxes per camera)

log = logging.getLogger("momloc.setup")
# Matched with fullmatch: ``$`` with ``match`` also accepts a trailing newline ("zz.npz\n").
SAFE_RECORDING_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,80}\.npz")


def check_recording_name(name: str, field: str) -> str:
    """``name`` when it is a plain ``.npz`` file name in the data directory, else MomlocError."""
    if not SAFE_RECORDING_NAME.fullmatch(name):
        raise MomlocError(f"{field} '{shorten(name, 90)}': use a plain file name ending in .npz")
    return name


class Cancelled(Exception):
    """The user pressed stop."""


class DetectionTap:
    """A feed fed by the pipeline: keeps only the newest frame set's detections."""

    def __init__(self, image_sizes: np.ndarray) -> None:
        self.image_sizes = np.asarray(image_sizes, np.int32)
        self._latest: FeedFrame | None = None
        self._new = threading.Condition()
        self.cancelled = threading.Event()

    def push(self, t: float, detections: list[np.ndarray]) -> None:
        """Called by the pipeline thread for every frame set; never blocks on the consumer."""
        with self._new:
            self._latest = FeedFrame(t, [np.asarray(d).reshape(-1, 4) for d in detections])
            self._new.notify_all()

    def prepare(self, steps: list[Step]) -> None:
        """People follow the page's instructions; nothing to script."""

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        """The frame sets of ``step``; a move step ends once the person has arrived
        (:mod:`service.setup.arrival`), its planned length is the maximum wait."""
        end = time.monotonic() + step.seconds
        last: FeedFrame | None = None
        arrival = Arrival(len(self.image_sizes)) if step.kind == "move" else None
        while time.monotonic() < end:
            if self.cancelled.is_set():
                raise Cancelled
            with self._new:
                self._new.wait_for(partial(self._changed_since, last), timeout=0.1)
                frame = self._latest
            if frame is not None and frame is not last:
                last = frame
                yield frame
                if arrival is not None and arrival.update(frame.t, frame.boxes):
                    return

    def _changed_since(self, seen: FeedFrame | None) -> bool:
        """Whether a frame set newer than ``seen`` arrived (called holding ``_new``)."""
        return self._latest is not seen

    def close(self) -> None:
        self.cancelled.set()


class SetupSession:
    """At most one web-driven collection; writes ``data_dir/<name>.npz``. ``steps`` is the
    set-up's state machine shared with training and the check (:mod:`service.setup.steps`)."""

    def __init__(
        self,
        data_dir: Path,
        image_sizes: Callable[[], list[tuple[int, int]] | None],
        attach: Callable[[DetectionListener], None],
        detach: Callable[[DetectionListener], None],
        steps: SetupSteps | None = None,
    ) -> None:
        self.data_dir = Path(data_dir)
        self.steps = SetupSteps() if steps is None else steps
        self._image_sizes = image_sizes  # the cameras' current sizes, None before all delivered
        self._attach, self._detach = attach, detach  # register/unregister a tap on the pipeline
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._tap: DetectionTap | None = None
        self._state: dict[str, Any] = {"state": "idle"}
        self._marks: list[FloorMark] = []
        self._done: set[str] = set()  # names of the marks recorded (this run or before)
        self._options: dict[str, Any] = {}
        self._quality: MarkQuality | None = None
        self._earlier_quality: list[dict[str, Any]] = []  # marks not in a record-again run
        self.last_recording: Path | None = None

    def start(
        self,
        marks: list[FloorMark],
        seconds: float,
        name: str,
        *,
        walk: bool = False,
        countdown_s: float = 3.0,
        move_s: float = 5.0,
    ) -> dict[str, Any]:
        check_recording_name(name, "out")
        self.steps.begin("record")
        try:
            return self._launch(marks, seconds, name, walk, countdown_s, move_s)
        except BaseException:
            self.steps.end("record")
            raise

    def _launch(
        self,
        marks: list[FloorMark],
        seconds: float,
        name: str,
        walk: bool,
        countdown_s: float,
        move_s: float,
    ) -> dict[str, Any]:
        """Start the collection thread; the caller holds the ``record`` step."""
        with self._lock:
            sizes = self._image_sizes()
            if sizes is None:
                raise MomlocError("cameras have not delivered frames yet; try again in a moment")
            self.data_dir.mkdir(parents=True, exist_ok=True)
            writer = DatasetAppender(self.data_dir / name, np.asarray(sizes, np.int32))
            done = [writer.has_mark(m) for m in marks]  # one pass: marks are bounded, rows not
            todo = [m for m, d in zip(marks, done, strict=True) if not d]
            if not todo:
                raise SetupConflict(f"all marks are already recorded in {name}")
            steps = plan_steps(
                todo,
                seconds,
                start=(todo[0].x, todo[0].y),
                walk=walk,
                move_s=move_s,
                countdown_s=countdown_s,
            )
            tap = DetectionTap(writer.image_sizes)
            self._tap = tap
            self._marks = list(marks)
            self._done = {m.name for m, d in zip(marks, done, strict=True) if d}
            self._options = {"seconds": seconds, "name": name, "walk": walk,
                             "countdown_s": countdown_s, "move_s": move_s}  # fmt: skip
            quality = MarkQuality(todo, writer.image_sizes.shape[0])
            self._quality = quality
            self._earlier_quality = []
            self.last_recording = writer.path
            self._state = {
                "state": "running",
                "out": str(writer.path.resolve()),
                "model_dir": str((self.data_dir / "model").resolve()),
                "steps": len(steps),
                "skipped_marks": [m.name for m, d in zip(marks, done, strict=True) if d],
                # rows from an interrupted run, recorded again in full (the old rows stay)
                "incomplete_marks": [m.name for m in todo if writer.has_rows_at(m)],
                "existing_rows": writer.existing_rows,
            }
            self._thread = threading.Thread(
                target=self._run,
                args=(tap, steps, writer, quality),
                name="momloc-setup",
                daemon=True,
            )
            self._attach(tap.push)
            self._thread.start()
        return self.status()

    def _run(
        self, tap: DetectionTap, steps: list[Step], writer: DatasetAppender, quality: MarkQuality
    ) -> None:
        error: str | None = None
        try:
            collect(tap, steps, quality.counting(writer), on_progress=self._on_progress)
            final = "done"
        except Cancelled:
            final = "stopped"
        except OSError as failure:  # a full disk, a removed folder: stop, say what is on disk
            final, error = "failed", f"writing {writer.path.name} failed: {shorten(failure, 300)}"
        except Exception as failure:  # shown on the page; the rows recorded are on disk
            final, error = "failed", shorten(failure, 300)
        finally:
            self._detach(tap.push)
            quality.finish()
        try:
            # rows on disk, not rows attempted: after a failed write the two differ
            unsaved = writer.new_rows - writer.saved_rows
            if error is not None:
                error = f"failed: {error}; {writer.saved_rows} new rows are on disk" + (
                    f", {unsaved} were not saved" if unsaved else ""
                )
                log.error("set-up recording %s %s", writer.path, error)  # once per collection
            self._state.update(
                state=final,
                error=error,
                new_rows=writer.saved_rows,
                unsaved_rows=unsaved,
                total_rows=writer.existing_rows + writer.saved_rows,
                instruction="all marks recorded" if final == "done" else "collection stopped",
            )
        finally:
            self.steps.end("record")  # the status is final: the next step may start

    def fault(self) -> str | None:
        """Why the last collection failed, if it did (``/v1/health`` shows it until the next)."""
        state = self._state
        return state.get("error") if state.get("state") == "failed" else None

    def _on_progress(self, progress: Progress) -> None:
        step = progress.step
        if self._quality is not None:
            self._quality.frame(step, progress.cameras_seeing)

        self._state.update(
            step_index=progress.step_index,
            kind=step.kind,
            instruction=step.instruction,
            target=None if step.mark is None else [step.end[0], step.end[1]],
            mark=None if step.mark is None else step.mark.name,
            fraction=round(progress.fraction, 3),
            remaining_s=round(max(0.0, (1 - progress.fraction) * step.seconds), 1),
            cameras_seeing=progress.cameras_seeing,
            new_rows=progress.kept_rows,
        )

    def stop(self) -> dict[str, Any]:
        tap, thread = self._tap, self._thread
        if tap is not None:
            tap.cancelled.set()
        if thread is not None:
            thread.join(timeout=5)
        return self.status()

    def status(self) -> dict[str, Any]:
        """The state, plus every mark of the plan (done / current / todo) and per-mark quality."""
        out = dict(self._state)
        quality = self._quality
        finished = set() if quality is None else set(quality.finished)
        current = out.get("mark") if out.get("state") == "running" else None
        out["marks"] = [
            {
                "name": m.name,
                "x": m.x,
                "y": m.y,
                "state": "done"
                if m.name in self._done or m.name in finished
                else "current"
                if m.name == current
                else "todo",
            }
            for m in self._marks
        ]
        out["quality"] = self._earlier_quality + ([] if quality is None else quality.report())
        return out

    def marks(self) -> list[FloorMark]:
        """The marks of the last collection plan (for the check step's default)."""
        return list(self._marks)

    def target(self) -> tuple[float, float] | None:
        """Where the instructions send the person now (the synthetic follower goes there)."""
        state = self._state
        if state.get("state") != "running" or state.get("mark") is None:
            return None
        target = state.get("target")
        return None if target is None else (float(target[0]), float(target[1]))

    def record_again(self, mark_name: str) -> dict[str, Any]:
        """Forget ``mark_name``'s rows in the last recording and record it alone again (one
        ``record`` step from the forgetting to the end, so nothing reads the file in between)."""
        self.steps.begin("record")
        try:
            mark = next((m for m in self._marks if m.name == mark_name), None)
            if mark is None or self.last_recording is None:
                known = ", ".join(m.name for m in self._marks) or "none: record marks first"
                raise MomlocError(
                    f"mark: '{shorten(mark_name, 40)}' is not a mark of the last recording "
                    f"({known})"
                )
            if self.last_recording.exists():
                forget_mark(self.last_recording, mark)
            marks, options = list(self._marks), dict(self._options)
            earlier = [q for q in self.status()["quality"] if q["mark"] != mark.name]
            finished = {q["mark"] for q in earlier}
            done = (self._done | finished) - {mark.name}
            self._launch(
                [mark],
                options["seconds"],
                options["name"],
                options["walk"],
                options["countdown_s"],
                options["move_s"],
            )
        except BaseException:
            self.steps.end("record")
            raise
        self._marks, self._done, self._earlier_quality = marks, done, earlier
        return self.status()
